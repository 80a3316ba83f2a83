//! Worker threads: take a file from the bounded queue, hash it, parse its
//! name, count it and store the outcome.
//!
//! Counting is blocking and CPU-heavy, so it runs on dedicated OS threads,
//! never on the tokio runtime. Every failure is recorded against the file and
//! logged; nothing a file contains can stop a worker (panics included).

use std::panic::AssertUnwindSafe;
use std::path::Path;
use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;

use tokio::sync::mpsc;

pub use super::job::{Job, Stats, WorkerCtx};
use crate::domain::names::ParsedName;
use crate::files::{mtime_string, sha256_hex};
use crate::pipeline::supervise::{panic_message, supervised, Lifeline};
use crate::store::{CountRecord, FileFacts, Outcome, Precheck, Recorded, Store};

/// Starts `n` worker threads sharing one receiver.
pub fn spawn_workers(
    n: usize,
    rx: mpsc::Receiver<Job>,
    ctx: Arc<WorkerCtx>,
) -> anyhow::Result<Vec<JoinHandle<()>>> {
    let rx = Arc::new(Mutex::new(rx));
    let mut handles = Vec::with_capacity(n);
    for i in 0..n {
        let mut store = Store::open(
            &ctx.config.database,
            &ctx.config.rules().timeline,
            ctx.config.inference.max_attempts,
        )?;
        let (rx, ctx) = (rx.clone(), ctx.clone());
        let h = std::thread::Builder::new()
            .name(format!("phyllo-worker-{i}"))
            .spawn(move || {
                let _life = Lifeline(ctx.clone());
                work_loop(&rx, &ctx, &mut store)
            })?;
        handles.push(h);
    }
    Ok(handles)
}

/// Takes jobs until the queue closes, each processed under supervision.
fn work_loop(rx: &Mutex<mpsc::Receiver<Job>>, ctx: &WorkerCtx, store: &mut Store) {
    loop {
        // Holding the lock while waiting is fine: whoever holds it takes the next job.
        let job = rx.lock().expect("receiver lock").blocking_recv();
        let Some(job) = job else { break };
        ctx.stats.queued.fetch_sub(1, Ordering::Relaxed);
        if ctx.shutdown.load(Ordering::SeqCst) {
            // Handed back: not recorded, so the next start's scan finds it again.
            ctx.in_flight.lock().expect("in_flight lock").remove(&job.path);
            continue;
        }
        ctx.stats.busy.fetch_add(1, Ordering::Relaxed);
        if let Err(e) = supervised(store, ctx, &job, |store| process(store, ctx, &job)) {
            ctx.stats.internal_errors.fetch_add(1, Ordering::Relaxed);
            tracing::error!("{}: {e:#}", job.path.display());
        }
        ctx.stats.busy.fetch_sub(1, Ordering::Relaxed);
        ctx.in_flight.lock().expect("in_flight lock").remove(&job.path);
    }
}

/// Largest file a worker reads, in bytes. A LemnaTec frame is 5–15 MB as PNG
/// and about 15 MB as uncompressed TIFF; the decoder's own limits stop at 40
/// megapixels. Anything bigger is refused before it is read, so a huge or
/// endless file in the drop directory cannot exhaust memory.
pub const MAX_FILE_BYTES: u64 = 256 << 20;

/// Why a file was not read: the file itself is the problem (it is recorded
/// as failed), as opposed to phyllo's own trouble (logged and retried).
struct Refused {
    error: String,
    retry: bool,
}

/// What reading a job's file gave.
enum Read {
    /// The content and the metadata of the opened file.
    Bytes(Vec<u8>, std::fs::Metadata),
    /// The file is gone: nothing to record.
    Vanished,
    /// The file cannot or must not be read; recorded against it.
    Refused(Refused, Option<std::fs::Metadata>),
}

/// Reads a job's file, refusing anything that resolves outside the drop
/// directory (a symbolic link, or a linked directory, pointing elsewhere),
/// symbolic-link loops, non-regular files and files over [`MAX_FILE_BYTES`].
///
/// The check is made on the *opened* file (`/proc/self/fd`), not on the path,
/// so a link swapped in between the check and the read cannot smuggle a file
/// from outside in. Links that stay inside the drop directory are followed.
fn read_inside(root: &Path, job: &Job) -> Read {
    let name = crate::domain::names::printable(&job.rel);
    let link_meta = std::fs::symlink_metadata(&job.path).ok();
    let refuse = |error: String, retry: bool| Read::Refused(Refused { error, retry }, link_meta.clone());
    let file = match std::fs::File::open(&job.path) {
        Ok(f) => f,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            return match &link_meta {
                Some(m) if m.file_type().is_symlink() => refuse(
                    format!("{name}: dangling symbolic link (its target does not exist)"),
                    false,
                ),
                _ => Read::Vanished,
            };
        }
        Err(e) if crate::files::too_long(&e) => {
            return refuse(
                format!(
                    "{name}: its path is {} bytes, longer than the {} the system can open: \
                     move it (or its folders) to a shorter path",
                    job.path.as_os_str().len(),
                    libc::PATH_MAX
                ),
                false,
            );
        }
        Err(e) if e.raw_os_error() == Some(40) => {
            // ELOOP
            return refuse(format!("{name}: symbolic link loop, not followed"), false);
        }
        Err(e) if e.kind() == std::io::ErrorKind::PermissionDenied => {
            // The operator may fix the permissions: retried up to max_attempts,
            // and again whenever the file turns readable (Store::is_known).
            return refuse(
                format!(
                    "{name}{}: {e} (fix its permissions: phyllo tries it again once it can read it)",
                    crate::store::PERMISSION_DENIED
                ),
                true,
            );
        }
        Err(e) => return refuse(format!("{name}: cannot open: {e}"), true),
    };
    let meta = match file.metadata() {
        Ok(m) => m,
        Err(e) => return refuse(format!("{name}: cannot stat: {e}"), true),
    };
    if !meta.is_file() {
        return refuse(format!("{name}: not a regular file"), false);
    }
    let real = std::fs::read_link(format!(
        "/proc/self/fd/{}",
        std::os::fd::AsRawFd::as_raw_fd(&file)
    ))
    .or_else(|_| std::fs::canonicalize(&job.path));
    let root = std::fs::canonicalize(root).unwrap_or_else(|_| root.to_path_buf());
    match real {
        Ok(real) if real.starts_with(&root) => {}
        Ok(real) => {
            return refuse(
                format!(
                    "{}: resolves to {}, outside the drop directory {}: not read",
                    name,
                    real.display(),
                    root.display()
                ),
                false,
            )
        }
        Err(e) => return refuse(format!("{name}: cannot resolve its real path: {e}"), true),
    }
    if meta.len() > MAX_FILE_BYTES {
        return refuse(
            format!(
                "{}: {} bytes is larger than the {} MiB limit for one image",
                name,
                meta.len(),
                MAX_FILE_BYTES >> 20
            ),
            false,
        );
    }
    let mut bytes = Vec::with_capacity(meta.len() as usize);
    // take(): the file may grow between the stat and the read.
    match std::io::Read::read_to_end(&mut std::io::Read::take(&file, MAX_FILE_BYTES + 1), &mut bytes) {
        Ok(_) if bytes.len() as u64 > MAX_FILE_BYTES => refuse(
            format!(
                "{}: larger than the {} MiB limit for one image",
                name,
                MAX_FILE_BYTES >> 20
            ),
            false,
        ),
        Ok(_) => Read::Bytes(bytes, meta),
        Err(e) => refuse(format!("{name}: read error: {e}"), true),
    }
}

/// Processes one file. Returns what the store did, `None` if it was skipped.
pub fn process(store: &mut Store, ctx: &WorkerCtx, job: &Job) -> anyhow::Result<Option<Recorded>> {
    // Held through the read, the decode and the count (crate::pipeline::memory).
    let _large = super::memory::large_file_permit(std::fs::metadata(&job.path).map_or(0, |m| m.len()));
    let (bytes, meta) = match read_inside(&ctx.config.drop_dir, job) {
        Read::Bytes(b, m) => (b, m),
        Read::Vanished => {
            tracing::debug!("{} vanished before it was read", job.rel);
            return Ok(None);
        }
        Read::Refused(r, link_meta) => return record_refused(store, ctx, job, r, link_meta),
    };
    let facts = FileFacts {
        rel: job.rel.clone(),
        size: bytes.len() as u64,
        mtime: Some(mtime_string(&meta)),
        sha256: sha256_hex(&bytes),
    };
    let rel = Path::new(&job.rel);
    let now = chrono::Local::now().naive_local();
    let names = &ctx.config.rules().names;
    let parsed = names
        .parse(rel)
        .and_then(|name| names.check_time(rel, name.taken_at, now).map(|()| name));
    let reused = match store.precheck(&facts, parsed.as_ref().ok())? {
        Precheck::Skip(why) => {
            tracing::debug!("skip: {why}");
            ctx.stats.skipped.fetch_add(1, Ordering::Relaxed);
            return Ok(None);
        }
        Precheck::Reuse { count, original } => Some((count, original)),
        Precheck::Process => None,
    };
    let recorded = match &parsed {
        Err(e) => {
            let error = format!("{e:#}");
            tracing::warn!("{error}");
            store.record(
                &facts,
                Outcome::Failed {
                    name: None,
                    error,
                    retry: false,
                },
            )?
        }
        Ok(name) => match reused {
            Some((count, original)) => record_reused(store, job, &facts, name, &count, &original)?,
            None => count_and_record(store, ctx, job, &facts, name, &bytes)?,
        },
    };
    if let (Recorded::Counted { .. }, Ok(name)) = (&recorded, &parsed) {
        // A misnamed or broken file renamed or replaced under a new name:
        // its old failure is moot once the old file is gone.
        let root = &ctx.config.drop_dir;
        let gone = |path: &str| !root.join(crate::domain::rel_path::decode(path)).exists();
        store.supersede_failures(&job.rel, &facts.sha256, name, gone)?;
    }
    match &recorded {
        Recorded::Counted { .. } => ctx.stats.counted.fetch_add(1, Ordering::Relaxed),
        Recorded::Failed => ctx.stats.failed.fetch_add(1, Ordering::Relaxed),
        Recorded::Duplicate(_) => ctx.stats.skipped.fetch_add(1, Ordering::Relaxed),
    };
    *ctx.stats.last.lock().expect("last lock") = Some(job.rel.clone());
    Ok(Some(recorded))
}

/// Records a file that was not read (a link out, a loop, too large, ...).
fn record_refused(
    store: &mut Store,
    ctx: &WorkerCtx,
    job: &Job,
    r: Refused,
    link_meta: Option<std::fs::Metadata>,
) -> anyhow::Result<Option<Recorded>> {
    // Size and mtime as the intake and scans see them (following links where
    // possible), so that rescans recognise the file as done.
    let seen = std::fs::metadata(&job.path).ok().or(link_meta);
    let facts = FileFacts {
        rel: job.rel.clone(),
        size: seen.as_ref().map_or(0, |m| m.len()),
        mtime: Some(seen.as_ref().map(mtime_string).unwrap_or_default()),
        // Not the content (it was not read): a stable marker of the refusal, so
        // the same refusal is recognised as unchanged and not recorded twice.
        sha256: sha256_hex(format!("phyllo-refused:{}", r.error).as_bytes()),
    };
    if let Precheck::Skip(why) = store.precheck(&facts, None)? {
        tracing::debug!("skip: {why}");
        ctx.stats.skipped.fetch_add(1, Ordering::Relaxed);
        return Ok(None);
    }
    tracing::warn!("{}", r.error);
    let recorded = store.record(
        &facts,
        Outcome::Failed {
            name: None,
            error: r.error,
            retry: r.retry,
        },
    )?;
    ctx.stats.failed.fetch_add(1, Ordering::Relaxed);
    *ctx.stats.last.lock().expect("last lock") = Some(job.rel.clone());
    Ok(Some(recorded))
}

/// Records an image whose bytes were counted under another identity, with
/// that count: not a duplicate, since the name says another plant, time or
/// view (or the path went back to an older version).
fn record_reused(
    store: &mut Store,
    job: &Job,
    facts: &FileFacts,
    name: &ParsedName,
    count: &CountRecord,
    original: &str,
) -> anyhow::Result<Recorded> {
    tracing::warn!(
        "{}: same bytes as {original}, counted there; its count ({} leaves) is reused for {} {} {}",
        job.rel,
        count.leaf_count,
        name.plant,
        name.taken_at,
        name.view
    );
    store.record(facts, Outcome::Counted(name, count))
}

/// Runs the model on the bytes (a panic in it fails the image) and records
/// the outcome.
fn count_and_record(
    store: &mut Store,
    ctx: &WorkerCtx,
    job: &Job,
    facts: &FileFacts,
    name: &ParsedName,
    bytes: &[u8],
) -> anyhow::Result<Recorded> {
    // The view parsed from the name goes along: the model is never left to
    // work it out from the file name again.
    let counted = std::panic::catch_unwind(AssertUnwindSafe(|| {
        ctx.counter.count(&job.path, &name.view, bytes)
    }));
    let (error, retry) = match counted {
        Ok(Ok(count)) => {
            let r = store.record(facts, Outcome::Counted(name, &count))?;
            tracing::info!(
                "{}: {} leaves ({} {}), {:.0} ms",
                job.rel,
                count.leaf_count,
                name.plant,
                name.view,
                count.ms_total
            );
            return Ok(r);
        }
        Ok(Err(e)) => {
            tracing::warn!("{}", e.message);
            (e.message, e.retry)
        }
        Err(panic) => {
            let error = format!(
                "{}: counting panicked: {}",
                job.path.display(),
                panic_message(&*panic)
            );
            tracing::error!("{error}");
            (error, false)
        }
    };
    store.record(
        facts,
        Outcome::Failed {
            name: Some(name),
            error,
            retry,
        },
    )
}
