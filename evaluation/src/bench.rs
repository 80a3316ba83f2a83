//! `phyllo bench`: per-stage timings of the inference path on full camera
//! frames, and the same frames through a straightforward Python pipeline
//! (PIL + numpy + onnxruntime, same model, same post-processing) measured in
//! the same run, so the ratio is not skewed by a noisy machine.

use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode};
use std::sync::mpsc::sync_channel;
use std::time::Instant;

use anyhow::{bail, Context};
use phyllo_inference::decode::decode_rgb;
use phyllo_inference::model::ModelInfo;
use phyllo_inference::{Counter, CounterConfig, StageTimings};
use serde_json::Value;

use crate::image_names::facts_for;

/// What `phyllo bench` times and beside what: every option but the model's,
/// which the caller turns into a [`CounterConfig`].
#[derive(Debug, Clone, clap::Args)]
pub struct BenchArgs {
    /// Directory of full-size PNG frames to time. Without it, frames are made
    /// by upscaling the real development images to 2454x2056 PNG.
    #[arg(long, value_name = "DIR")]
    pub frames: Option<PathBuf>,
    /// Where to find images to upscale when --frames is not given.
    #[arg(
        long,
        value_name = "DIR",
        default_value = "../shared/data/unl-maize-dev/images"
    )]
    pub source: PathBuf,
    /// Number of frames to make when --frames is not given.
    #[arg(long, default_value_t = 8)]
    pub n: usize,
    /// Passes over the frames.
    #[arg(long, default_value_t = 3)]
    pub repeat: usize,
    /// Python interpreter for the reference pipeline ("none" to skip it).
    #[arg(long, default_value = "python3")]
    pub python: String,
}

/// Runs the benchmark and prints its table. `config` gives the model's
/// configuration (the caller's model options); it is called once the frames
/// are in place.
pub fn run(
    args: &BenchArgs,
    config: impl FnOnce() -> anyhow::Result<CounterConfig>,
) -> anyhow::Result<ExitCode> {
    let frames = Frames::prepare(args)?;
    let counter = Counter::new(config()?)?;
    let info = counter.model_info().clone();
    print_header(&info, &frames, args.repeat);
    let timed = Sequential::time(&counter, &frames.paths, args.repeat)?;
    let pipelined_s = pipelined(&counter, &frames.paths, args.repeat)?;
    let python = if args.python == "none" {
        None
    } else {
        match python_reference(&args.python, &info.path, &frames.dir, args.repeat) {
            Ok(p) => Some(p),
            Err(e) => {
                eprintln!("phyllo bench: Python reference pipeline skipped: {e:#}");
                None
            }
        }
    };
    print_stages(&timed, python.as_ref());
    print_throughput(&counter, &frames.paths, &timed, pipelined_s, python.as_ref())?;
    Ok(ExitCode::SUCCESS)
}

/// The frames to time: `--frames`, or frames made into a temporary directory.
struct Frames {
    /// Where they are.
    dir: PathBuf,
    /// The PNG files, sorted.
    paths: Vec<PathBuf>,
    /// The temporary directory of made frames, removed when dropped.
    _made: Option<tempfile::TempDir>,
}

impl Frames {
    fn prepare(args: &BenchArgs) -> anyhow::Result<Self> {
        let (dir, made) = match &args.frames {
            Some(d) => (d.clone(), None),
            None => {
                let tmp = tempfile::tempdir().context("cannot create a temporary directory")?;
                make_frames(&args.source, tmp.path(), args.n)?;
                (tmp.path().to_path_buf(), Some(tmp))
            }
        };
        let paths = list_frames(&dir)?;
        Ok(Self {
            dir,
            paths,
            _made: made,
        })
    }
}

fn print_header(info: &ModelInfo, frames: &Frames, repeat: usize) {
    println!("model        {} ({})", info.id(), info.path.display());
    println!(
        "ONNX Runtime {}",
        phyllo_inference::runtime::loaded_path()
            .map(|p| p.display().to_string())
            .unwrap_or_default()
    );
    println!(
        "frames       {} x {} passes from {}",
        frames.paths.len(),
        repeat,
        frames.dir.display()
    );
}

/// The frames counted one at a time, each pass in turn.
struct Sequential {
    /// Each count's stage timings.
    per_image: Vec<StageTimings>,
    /// Tiles over all counts.
    tiles: u64,
    /// Wall time of all passes.
    seconds: f64,
}

impl Sequential {
    /// Counts every frame `repeat` times after one warm-up count.
    fn time(counter: &Counter, frames: &[PathBuf], repeat: usize) -> anyhow::Result<Self> {
        // Warm-up: the first run pays for ONNX Runtime's allocations.
        counter.count_path(&frames[0], &facts_for(&frames[0]))?;
        let mut per_image = Vec::new();
        let mut tiles = 0u64;
        let t0 = Instant::now();
        for _ in 0..repeat {
            for f in frames {
                let r = counter.count_path(f, &facts_for(f))?;
                tiles += u64::from(r.tiles);
                per_image.push(r.ms);
            }
        }
        Ok(Self {
            per_image,
            tiles,
            seconds: t0.elapsed().as_secs_f64(),
        })
    }

    fn mean(&self, f: StageField) -> f64 {
        self.per_image.iter().map(f).sum::<f64>() / self.per_image.len() as f64
    }

    fn p50(&self, f: StageField) -> f64 {
        let mut v: Vec<f64> = self.per_image.iter().map(f).collect();
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    }

    fn tiles_per_image(&self) -> f64 {
        self.tiles as f64 / self.per_image.len() as f64
    }
}

/// Reads one stage's time out of [`StageTimings`].
type StageField = fn(&StageTimings) -> f64;

/// The table of milliseconds per stage, beside the Python pipeline's.
fn print_stages(timed: &Sequential, python: Option<&Value>) {
    println!();
    println!("| stage (ms per 2454x2056 PNG) | phyllo mean | phyllo p50 | python mean |");
    println!("|---|---:|---:|---:|");
    let stages: [(&str, StageField, &str); 5] = [
        ("decode", |t| t.decode, "decode"),
        ("region + scale + tile", |t| t.tile, "tile"),
        ("inference (ONNX Runtime)", |t| t.inference, "inference"),
        ("stitch + post-processing", |t| t.postprocess, "postprocess"),
        ("total", |t| t.total, "total"),
    ];
    for (name, f, key) in stages {
        let py = python.and_then(|p| p.get(key)).and_then(|v| v.as_f64());
        println!(
            "| {name} | {:.1} | {:.1} | {} |",
            timed.mean(f),
            timed.p50(f),
            fmt_opt(py)
        );
    }
    println!(
        "| post-processing per 512 tile | {:.2} | | {} |",
        timed.mean(|t| t.postprocess) / timed.tiles_per_image(),
        fmt_opt(
            python.and_then(|p| Some(p.get("postprocess")?.as_f64()? / p.get("tiles_per_image")?.as_f64()?))
        )
    );
}

/// Images per second each way, and the Python pipeline's counts against ours.
fn print_throughput(
    counter: &Counter,
    frames: &[PathBuf],
    timed: &Sequential,
    pipelined_s: f64,
    python: Option<&Value>,
) -> anyhow::Result<()> {
    println!();
    let n = timed.per_image.len() as f64;
    let seq_ips = n / timed.seconds;
    let pipe_ips = n / pipelined_s;
    println!("tiles per image            {:.2}", timed.tiles_per_image());
    println!("images/s, one at a time    {seq_ips:.2}");
    println!("images/s, decode ahead     {pipe_ips:.2}");
    let Some(py_ips) = python
        .and_then(|p| p.get("images_per_s"))
        .and_then(|v| v.as_f64())
    else {
        return Ok(());
    };
    println!("images/s, Python reference {py_ips:.2}");
    println!(
        "speed-up vs Python         {:.2}x (decode ahead) / {:.2}x (one at a time)",
        pipe_ips / py_ips,
        seq_ips / py_ips
    );
    if let Some(theirs) = python.and_then(|p| p.get("counts")).and_then(|v| v.as_array()) {
        print_agreement(counter, frames, theirs)?;
    }
    Ok(())
}

/// How many frames phyllo and the Python pipeline count alike, and the others.
fn print_agreement(counter: &Counter, frames: &[PathBuf], theirs: &[Value]) -> anyhow::Result<()> {
    let ours: Vec<u32> = frames
        .iter()
        .map(|f| counter.count_path(f, &facts_for(f)).map(|r| r.leaf_count))
        .collect::<Result<_, _>>()?;
    let theirs: Vec<u64> = theirs.iter().filter_map(|v| v.as_u64()).collect();
    let same = ours
        .iter()
        .zip(&theirs)
        .filter(|(a, b)| u64::from(**a) == **b)
        .count();
    println!("same leaf count as Python  {same}/{}", ours.len());
    for ((f, a), b) in frames.iter().zip(&ours).zip(&theirs) {
        if u64::from(*a) != *b {
            println!("  {}: phyllo {a}, Python {b}", f.display());
        }
    }
    Ok(())
}

fn fmt_opt(v: Option<f64>) -> String {
    v.map(|v| format!("{v:.1}")).unwrap_or_else(|| "-".into())
}

/// Decodes on one thread while the model runs on another, the way the
/// daemon's workers overlap I/O with inference; returns the wall time.
fn pipelined(counter: &Counter, frames: &[PathBuf], repeat: usize) -> anyhow::Result<f64> {
    let limits = counter.config().limits;
    let t0 = Instant::now();
    std::thread::scope(|s| -> anyhow::Result<()> {
        let (tx, rx) = sync_channel(2);
        s.spawn(move || {
            for _ in 0..repeat {
                for f in frames {
                    let img = std::fs::read(f)
                        .map_err(|e| anyhow::anyhow!("{}: {e}", f.display()))
                        .and_then(|b| decode_rgb(f, &b, &limits).map_err(anyhow::Error::from));
                    if tx.send(img).is_err() {
                        return;
                    }
                }
            }
        });
        for img in rx {
            counter.analyse_image(&img?)?;
        }
        Ok(())
    })?;
    Ok(t0.elapsed().as_secs_f64())
}

fn list_frames(dir: &Path) -> anyhow::Result<Vec<PathBuf>> {
    let mut frames: Vec<PathBuf> = std::fs::read_dir(dir)
        .with_context(|| format!("cannot read {}", dir.display()))?
        .filter_map(Result::ok)
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|e| e.eq_ignore_ascii_case("png")))
        .collect();
    frames.sort();
    if frames.is_empty() {
        bail!("{} holds no .png frames", dir.display());
    }
    Ok(frames)
}

/// Writes `n` full-size 2454x2056 PNG frames made from the images in `source`.
pub fn make_frames(source: &Path, out: &Path, n: usize) -> anyhow::Result<()> {
    let mut imgs: Vec<PathBuf> = std::fs::read_dir(source)
        .with_context(|| {
            format!(
                "no --frames given and cannot read {} to make frames",
                source.display()
            )
        })?
        .filter_map(Result::ok)
        .map(|e| e.path())
        .filter(|p| {
            p.extension()
                .is_some_and(|e| e.eq_ignore_ascii_case("jpg") || e.eq_ignore_ascii_case("png"))
        })
        .collect();
    imgs.sort();
    if imgs.is_empty() {
        bail!("{} holds no images to make frames from", source.display());
    }
    for (i, src) in imgs.iter().cycle().take(n).enumerate() {
        let img = image::open(src).with_context(|| format!("cannot open {}", src.display()))?;
        let big = img
            .resize_exact(2454, 2056, image::imageops::FilterType::Triangle)
            .into_rgb8();
        let dst = out.join(format!("frame{i:03}.png"));
        big.save(&dst)
            .with_context(|| format!("cannot write {}", dst.display()))?;
    }
    Ok(())
}

/// Runs `models/reference_pipeline.py` and returns its JSON summary.
pub fn python_reference(
    python: &str,
    model: &Path,
    frames: &Path,
    repeat: usize,
) -> anyhow::Result<serde_json::Value> {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../models/reference_pipeline.py");
    let out = Command::new(python)
        .arg(&script)
        .arg("--model")
        .arg(model)
        .arg("--frames")
        .arg(frames)
        .arg("--repeat")
        .arg(repeat.to_string())
        .output()
        .with_context(|| format!("cannot run {python}"))?;
    if !out.status.success() {
        bail!(
            "{} failed: {}",
            script.display(),
            String::from_utf8_lossy(&out.stderr).trim()
        );
    }
    let text = String::from_utf8_lossy(&out.stdout);
    let last = text.lines().last().unwrap_or_default();
    serde_json::from_str(last).with_context(|| format!("{} printed no JSON summary", script.display()))
}
