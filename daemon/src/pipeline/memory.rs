//! A memory bound for large images. Decoding costs about three times a
//! file's bytes (the file, the decoded pixels, the model's canvas): two
//! workers on two 250 MiB PNGs took the service from 0.4 to 1.5 GB. Files
//! over [`LARGE_FILE_BYTES`] are therefore read, decoded and counted one at a
//! time across all workers, while small ones go on in parallel; the unit's
//! `MemoryMax=` is the backstop.

use std::sync::{Mutex, MutexGuard};

/// Files larger than this take the one large-file permit (a LemnaTec frame
/// is 5–15 MB).
pub const LARGE_FILE_BYTES: u64 = 32 << 20;

static LARGE_FILE: Mutex<()> = Mutex::new(());

/// Waits for, and holds until dropped, the large-file permit when a file of
/// `size` bytes needs it; `None` for a small file.
pub fn large_file_permit(size: u64) -> Option<MutexGuard<'static, ()>> {
    // A worker that panicked while holding the permit leaves it poisoned, not taken.
    (size > LARGE_FILE_BYTES).then(|| LARGE_FILE.lock().unwrap_or_else(|p| p.into_inner()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::{Duration, Instant};

    #[test]
    fn large_files_go_one_at_a_time_and_small_ones_never_wait() {
        let held = large_file_permit(LARGE_FILE_BYTES + 1).expect("a large file takes the permit");
        assert!(
            large_file_permit(LARGE_FILE_BYTES).is_none(),
            "a small file waits for nothing"
        );
        let other = std::thread::spawn(|| {
            let t = Instant::now();
            let _permit = large_file_permit(250 << 20);
            t.elapsed()
        });
        std::thread::sleep(Duration::from_millis(300));
        drop(held);
        let waited = other.join().unwrap();
        assert!(
            waited >= Duration::from_millis(250),
            "the second large file waited {waited:?}"
        );
    }
}
