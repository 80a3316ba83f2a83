//! The daemon's TOML configuration.
//!
//! Only `drop_dir` and `database` are required; every other key has a default
//! chosen for the UNL LemnaTec facility. Every key is documented, with its
//! default, in `systemd/phyllo.toml.example`; a unit test checks that the
//! example parses and that it mentions every key, so the two cannot drift.
//! Unknown keys are refused (`deny_unknown_fields`) so that a typo is an error
//! at start-up rather than a silently ignored setting.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use serde::Deserialize;

use crate::files::identity::resolved;

mod rules;

pub use rules::Rules;

pub use crate::domain::climate_zone::ZoneConfig;
pub use crate::domain::groups::GroupsConfig;
pub use crate::domain::names::{NamesConfig, PatternConfig};
pub use crate::domain::timeline::TimelineConfig;

/// The whole configuration file.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Config {
    /// Directory the imaging station drops images into; watched recursively.
    pub drop_dir: PathBuf,
    /// SQLite database file (created with its parent directory if missing).
    pub database: PathBuf,
    /// How the drop directory is watched.
    #[serde(default)]
    pub watch: WatchConfig,
    /// How file names map to plant, time and view.
    #[serde(default)]
    pub names: NamesConfig,
    /// The worker pool and the model.
    #[serde(default)]
    pub inference: InferenceConfig,
    /// How views are fused and the timeline is fitted.
    #[serde(default)]
    pub timeline: TimelineConfig,
    /// Where `phyllo export` writes when no `--out` is given.
    #[serde(default)]
    pub export: ExportConfig,
    /// How long `phyllo tail`'s feed keeps its entries.
    #[serde(default)]
    pub feed: FeedConfig,
    /// Where `phyllo backup` (and its nightly timer) keeps database snapshots.
    #[serde(default)]
    pub backup: BackupConfig,
    /// How plant ids map to groups (genotype, treatment) for group summaries.
    #[serde(default)]
    pub groups: GroupsConfig,
    /// A folder of CSVs (temperature logs, people's counts) `phyllo import --dir` takes.
    #[serde(default)]
    pub import: ImportConfig,
    /// The rules above, compiled by [`Config::parse`].
    #[serde(skip, default = "Rules::defaults")]
    rules: Rules,
}

/// `[import]`: where the greenhouse's climate computer (or people) leave CSVs
/// for `phyllo import --dir`, which phyllo-import.timer runs hourly.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ImportConfig {
    /// The folder; unset: `phyllo import --dir` needs one on its command line.
    pub dir: Option<PathBuf>,
}

/// Most worker or ONNX Runtime threads a configuration may ask for: far
/// above any imaging station's cores, far below what exhausts memory.
const MAX_THREADS: u64 = 256;

/// `[watch]`: intake from the drop directory.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct WatchConfig {
    /// File extensions (case-insensitive, without dot) that are images.
    pub extensions: Vec<String>,
    /// Skip files and directories whose name starts with a dot: writers that
    /// rename into place usually write a hidden temporary first.
    pub ignore_hidden: bool,
    /// Seconds a file's size and mtime must stay unchanged before it is taken,
    /// for writers that keep the file open (no close-after-write event).
    pub stable_secs: f64,
    /// Milliseconds a file must stay unchanged after a close-after-write or a
    /// rename into the tree: guards against writers that close and reopen.
    pub settle_ms: u64,
    /// How often pending files are checked for stability, in milliseconds.
    pub poll_ms: u64,
    /// Seconds between full rescans of the drop directory (safety net for
    /// lost events, queue overflow, a recreated directory). 0 disables.
    pub rescan_secs: u64,
    /// Hours without a new image after which `phyllo status --check` warns:
    /// the imaging station, its network share or the drop directory may have
    /// stopped. 0 turns the warning off (a site that images on some days only).
    pub quiet_hours: f64,
    /// Leave top-view images alone (not read, not counted). Only the `max`
    /// fusion rule uses them, so a station that takes one top view per five
    /// side views saves a sixth of the counting.
    pub skip_top_views: bool,
}

impl Default for WatchConfig {
    fn default() -> Self {
        Self {
            extensions: ["png", "jpg", "jpeg", "tif", "tiff"]
                .iter()
                .map(|s| s.to_string())
                .collect(),
            ignore_hidden: true,
            stable_secs: 5.0,
            settle_ms: 300,
            poll_ms: 250,
            rescan_secs: 600,
            quiet_hours: 48.0,
            skip_top_views: false,
        }
    }
}

/// `[inference]`: worker pool and model.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct InferenceConfig {
    /// ONNX model file; unset means the model shipped with phyllo.
    pub model: Option<PathBuf>,
    /// ONNX Runtime shared library; unset means the one found at build time
    /// or through `ORT_DYLIB_PATH`.
    pub ort_lib: Option<PathBuf>,
    /// Worker threads taking images from the queue (hash, decode, count, store).
    pub workers: usize,
    /// ONNX Runtime intra-op threads per run.
    pub intra_threads: usize,
    /// Tiles per ONNX Runtime batch.
    pub batch_size: usize,
    /// Images waiting between intake and the workers; intake waits when full.
    pub queue_capacity: usize,
    /// Attempts for an image whose failure may be transient (runtime errors).
    /// Undecodable images and unmatched names are never retried for the same
    /// content.
    pub max_attempts: u32,
    /// Count small plants again, enlarged, when their leaves span fewer model
    /// rows than this (0: never); unset means the contract's
    /// `zoom_plant_height`.
    pub zoom_plant_height: Option<u32>,
    /// Also run every tile mirrored and average the two (twice the model
    /// time; not measurably more accurate on the shipped model).
    pub flip: bool,
    /// The side camera's zoom relative to the contract's: `"measure"` it on
    /// the chamber's back panel (default), `"contract"`, or a number.
    pub camera_zoom: phyllo_inference::camera_scale::CameraZoom,
    /// Per-station zooms by file-name pattern; the first match wins.
    pub camera_zoom_rules: Vec<crate::domain::image_facts::CameraZoomRule>,
    /// `[inference.top_views]`: the model that counts top views (`model`:
    /// `"default"`, `"none"` or a file), its `center_threshold` and
    /// `nms_kernel`, and the deprecated `files` (`[names]` tells top views).
    pub top_views: crate::domain::image_facts::TopViewsConfig,
}

impl Default for InferenceConfig {
    fn default() -> Self {
        Self {
            model: None,
            ort_lib: None,
            workers: 2,
            intra_threads: 2,
            batch_size: 4,
            queue_capacity: 64,
            max_attempts: 3,
            zoom_plant_height: None,
            flip: false,
            camera_zoom: Default::default(),
            camera_zoom_rules: Vec::new(),
            top_views: Default::default(),
        }
    }
}

/// `[export]`: defaults for `phyllo export` (and the nightly timer).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ExportConfig {
    /// Directory for `phyllo export` without `--out`: one `<what>.csv` per
    /// table. Unset means `exports/` beside the database.
    pub dir: Option<PathBuf>,
    /// Whether `phyllo export` without `--out` also draws every plant's
    /// timeline into `<dir>/plots/<plant>.png`.
    pub plots: bool,
    /// The nightly plots' x axis: `days`, or `degree-days` of the imported
    /// temperature log (a plant the log does not cover is drawn in days).
    pub plot_axis: PlotAxis,
}

/// What the nightly plots' x axis measures (`[export] plot_axis`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum PlotAxis {
    /// Days since the plant's first session.
    #[default]
    Days,
    /// Degree-days of the temperature log since the first session.
    DegreeDays,
}

impl Default for ExportConfig {
    fn default() -> Self {
        Self {
            dir: None,
            plots: true,
            plot_axis: PlotAxis::Days,
        }
    }
}

/// `[feed]`: retention of the feed `phyllo tail` follows. The feed repeats
/// what the images, observations and events tables keep for good, so old
/// entries can go; without a limit it grows by one row per image for as long
/// as the service runs.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct FeedConfig {
    /// Days a feed entry is kept (0 keeps every entry).
    pub keep_days: f64,
}

impl Default for FeedConfig {
    fn default() -> Self {
        Self { keep_days: 30.0 }
    }
}

impl FeedConfig {
    /// The retention as a duration, `None` when entries are kept for good.
    pub fn keep(&self) -> Option<std::time::Duration> {
        (self.keep_days > 0.0).then(|| std::time::Duration::from_secs_f64(self.keep_days * 86_400.0))
    }
}

/// `[backup]`: nightly snapshots of the database. The CSV exports hold the
/// timelines but not the image ledger (paths, hashes, failures) that lets a
/// restored service pick up where it stopped, so the database itself is kept.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct BackupConfig {
    /// Directory of the snapshots. Unset means `backups/` beside the database.
    pub dir: Option<PathBuf>,
    /// The newest snapshots kept; older ones are deleted after each new one
    /// (0 keeps all).
    pub keep: usize,
    /// Beyond those, the newest snapshot of each of this many earlier months.
    pub keep_monthly: usize,
}

impl Default for BackupConfig {
    fn default() -> Self {
        Self {
            dir: None,
            keep: 14,
            keep_monthly: 6,
        }
    }
}

impl Config {
    /// Reads and validates a configuration file. Relative paths in it are
    /// taken relative to the file's directory (a service's working directory
    /// is `/`, an operator's is anywhere; the file is the one fixed point).
    pub fn load(path: &Path) -> anyhow::Result<Config> {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("reading config file {}", path.display()))?;
        let mut cfg = Self::parse(&text).with_context(|| format!("config file {}", path.display()))?;
        let base = path.parent().unwrap_or(Path::new(""));
        let fix = |p: &mut PathBuf| {
            if p.is_relative() {
                *p = base.join(&*p);
            }
        };
        fix(&mut cfg.drop_dir);
        fix(&mut cfg.database);
        for p in [
            &mut cfg.inference.model,
            &mut cfg.inference.ort_lib,
            &mut cfg.export.dir,
            &mut cfg.backup.dir,
            &mut cfg.import.dir,
        ]
        .into_iter()
        .flatten()
        {
            fix(p);
        }
        cfg.check_own_dirs()
            .with_context(|| format!("config file {}", path.display()))?;
        Ok(cfg)
    }

    /// Refuses a drop directory that holds the service's own files: exported
    /// plots there would be counted as images (and fail), snapshots and the
    /// database would be scanned with every rescan. Compared by where the
    /// paths lead (symlinks followed), not by how they are spelled.
    fn check_own_dirs(&self) -> anyhow::Result<()> {
        let drop = resolved(&self.drop_dir);
        let own = [
            ("the database", self.database.clone()),
            ("[export] dir", self.export_dir()),
            ("[backup] dir", self.backup_dir()),
        ];
        for (what, dir) in own {
            if resolved(&dir).starts_with(&drop) {
                bail!(
                    "{what} ({}) lies inside the drop directory ({}): the service would read its own \
                     files as images; keep the drop directory for the imaging station alone",
                    dir.display(),
                    self.drop_dir.display()
                );
            }
        }
        Ok(())
    }

    /// Parses and validates configuration text.
    pub fn parse(text: &str) -> anyhow::Result<Config> {
        let mut cfg: Config = toml::from_str(text)?;
        cfg.validate()?;
        cfg.rules = Rules::compile(&cfg)?;
        Ok(cfg)
    }

    /// The compiled name patterns, timeline and group rules.
    pub fn rules(&self) -> &Rules {
        &self.rules
    }

    fn validate(&self) -> anyhow::Result<()> {
        if self.inference.workers == 0 {
            bail!("inference.workers must be at least 1");
        }
        if self.inference.queue_capacity == 0 {
            bail!("inference.queue_capacity must be at least 1");
        }
        check_camera_zooms(&self.inference)?;
        check_top_views(&self.inference)?;
        if self.timeline.living_window.is_multiple_of(2) {
            bail!("timeline.living_window must be odd (1 disables smoothing)");
        }
        if !(self.timeline.death_penalty >= 0.0 && self.timeline.death_penalty.is_finite()) {
            bail!("timeline.death_penalty must be 0 (read no deaths) or a positive number");
        }
        if !(-10.0..=40.0).contains(&self.timeline.base_temp_c) {
            bail!("timeline.base_temp_c must be a base temperature in °C, between -10 and 40");
        }
        if !(self.timeline.session_gap_minutes > 0.0 && self.timeline.session_gap_minutes.is_finite()) {
            bail!("timeline.session_gap_minutes must be a positive number of minutes");
        }
        self.check_ranges()?;
        if !(self.watch.quiet_hours >= 0.0 && self.watch.quiet_hours.is_finite()) {
            bail!("watch.quiet_hours must be 0 (no warning) or a positive number of hours");
        }
        if !(self.feed.keep_days >= 0.0 && self.feed.keep_days.is_finite()) {
            bail!("feed.keep_days must be 0 (keep every entry) or a positive number of days");
        }
        Ok(())
    }

    /// Paths that must name something and numbers that must lie in a range a
    /// station can use: refused here, at load, before the database is opened,
    /// rather than as a panic or a flood of errors later.
    fn check_ranges(&self) -> anyhow::Result<()> {
        for (key, path) in [("drop_dir", &self.drop_dir), ("database", &self.database)] {
            if path.as_os_str().is_empty() {
                bail!("{key} must name a path, not be empty");
            }
        }
        let w = &self.watch;
        if !(w.stable_secs >= 0.0 && w.stable_secs <= 86_400.0) {
            bail!(
                "watch.stable_secs must be a number of seconds from 0 to 86400, not {}",
                w.stable_secs
            );
        }
        let i = &self.inference;
        let whole = [
            ("watch.settle_ms", w.settle_ms, 0, 3_600_000),
            ("watch.poll_ms", w.poll_ms, 1, 60_000),
            ("watch.rescan_secs", w.rescan_secs, 0, 7 * 86_400),
            ("inference.workers", i.workers as u64, 1, MAX_THREADS),
            ("inference.intra_threads", i.intra_threads as u64, 0, MAX_THREADS),
            ("inference.batch_size", i.batch_size as u64, 1, 64),
            ("inference.queue_capacity", i.queue_capacity as u64, 1, 100_000),
            ("inference.max_attempts", u64::from(i.max_attempts), 1, 100),
            (
                "inference.zoom_plant_height",
                u64::from(i.zoom_plant_height.unwrap_or(0)),
                0,
                8192,
            ),
        ];
        for (key, value, lo, hi) in whole {
            if !(lo..=hi).contains(&value) {
                bail!("{key} must lie in {lo}..={hi}, not {value}");
            }
        }
        Ok(())
    }

    /// The directory holding the database (the service's state directory).
    pub fn state_dir(&self) -> PathBuf {
        match self.database.parent() {
            Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
            _ => PathBuf::from("."),
        }
    }

    /// Directory of the database snapshots `phyllo backup` writes.
    pub fn backup_dir(&self) -> PathBuf {
        match &self.backup.dir {
            Some(d) => d.clone(),
            None => self.state_dir().join("backups"),
        }
    }

    /// Directory `phyllo export` writes to without `--out`.
    pub fn export_dir(&self) -> PathBuf {
        match &self.export.dir {
            Some(d) => d.clone(),
            None => self.state_dir().join("exports"),
        }
    }
}

/// Refuses camera zooms outside the believable range, naming the setting.
fn check_camera_zooms(cfg: &InferenceConfig) -> anyhow::Result<()> {
    use phyllo_inference::camera_scale::CameraZoom;
    let check = |what: String, zoom: CameraZoom| match zoom {
        CameraZoom::Fixed(z) => CameraZoom::fixed(z)
            .map(|_| ())
            .map_err(|e| anyhow::anyhow!("{what}: {e}")),
        CameraZoom::Rule(_) => Ok(()),
    };
    check("inference.camera_zoom".into(), cfg.camera_zoom)?;
    for (i, rule) in cfg.camera_zoom_rules.iter().enumerate() {
        let what = format!("inference.camera_zoom_rules[{i}] (files = {:?})", rule.files);
        if rule.files.is_empty() {
            bail!("{what}: `files` must be a file-name pattern such as \"81-*\"");
        }
        check(what, rule.camera_zoom)?;
    }
    Ok(())
}

/// Refuses top-view settings that could never work, naming the setting.
fn check_top_views(cfg: &InferenceConfig) -> anyhow::Result<()> {
    let top = &cfg.top_views;
    if let Some(i) = top.files.iter().position(String::is_empty) {
        bail!("inference.top_views.files[{i}]: an empty pattern matches no file name; use e.g. \"*_TV_*\"");
    }
    if let Some(files) = top.legacy_files() {
        tracing::warn!(
            "inference.top_views.files = {files:?} is deprecated: the [names] patterns tell top views \
             (their `kind` group); until the key is removed these patterns still decide which images \
             the top-view model counts"
        );
    }
    if let Some(t) = top
        .center_threshold
        .filter(|t| !(t.is_finite() && *t > 0.0 && *t < 1.0))
    {
        bail!("inference.top_views.center_threshold = {t}: a centre threshold lies between 0 and 1");
    }
    if let Some(k) = top.nms_kernel.filter(|k| k.is_multiple_of(2) || *k > 31) {
        bail!("inference.top_views.nms_kernel = {k}: the window is odd, 1 to 31 output pixels");
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn minimal_config_works() {
        let cfg = Config::parse(
            "drop_dir = \"/srv/phenotyping/drop\"\ndatabase = \"/var/lib/phyllo/phyllo.sqlite\"\n",
        )
        .unwrap();
        assert_eq!(cfg.inference.workers, 2);
        assert_eq!(cfg.timeline.fusion, "second-max-side");
        assert_eq!(cfg.export_dir(), PathBuf::from("/var/lib/phyllo/exports"));
        assert_eq!(cfg.backup_dir(), PathBuf::from("/var/lib/phyllo/backups"));
        assert_eq!(cfg.backup.keep, 14);
    }

    #[test]
    fn unknown_keys_are_refused() {
        let err = Config::parse("drop_dir = \"/d\"\ndatabase = \"/db\"\n[watch]\nrescan = 3\n").unwrap_err();
        assert!(format!("{err:#}").contains("unknown field"), "{err:#}");
    }

    /// Top views are told by name and counted by their own model.
    #[test]
    fn top_view_settings_are_read_and_bad_ones_named() {
        use phyllo_inference::top_view::TopModel;
        let base = "drop_dir = \"/d\"\ndatabase = \"/db\"\n[inference.top_views]\n";
        let cfg = Config::parse(&format!("{base}model = \"none\"\nfiles = [\"*_TOP_*\"]\n")).unwrap();
        assert_eq!(cfg.inference.top_views.model, TopModel::Off);
        assert_eq!(cfg.inference.top_views.files, ["*_TOP_*"]);
        let counter = crate::counting::counter_config(&cfg.inference);
        assert_eq!(counter.top_views, cfg.inference.top_views);
        let default = Config::parse("drop_dir = \"/d\"\ndatabase = \"/db\"\n").unwrap();
        assert_eq!(default.inference.top_views.model, TopModel::Default);
        for (bad, names) in [
            ("files = [\"\"]", "files[0]"),
            ("center_threshold = 1.5", "center_threshold"),
            ("nms_kernel = 4", "nms_kernel"),
        ] {
            let err = format!("{:#}", Config::parse(&format!("{base}{bad}\n")).unwrap_err());
            assert!(err.contains(names), "{bad}: {err}");
        }
    }

    /// Issue 41: a station pins its camera's zoom, outright or by file name.
    #[test]
    fn camera_zooms_are_read_and_a_bad_one_names_its_rule() {
        use phyllo_inference::camera_scale::CameraZoom;
        let text = "drop_dir = \"/d\"\ndatabase = \"/db\"\n[inference]\ncamera_zoom = \"contract\"\n\
                    [[inference.camera_zoom_rules]]\nfiles = \"81-*\"\ncamera_zoom = 2\n";
        let cfg = Config::parse(text).unwrap();
        assert_eq!(cfg.inference.camera_zoom, "contract".parse().unwrap());
        assert_eq!(
            cfg.inference.camera_zoom_rules[0].camera_zoom,
            CameraZoom::Fixed(2.0)
        );
        let counter = crate::counting::counter_config(&cfg.inference);
        assert_eq!(counter.camera_zoom_rules, cfg.inference.camera_zoom_rules);
        let bad = text.replace("camera_zoom = 2", "camera_zoom = 0.1");
        let err = format!("{:#}", Config::parse(&bad).unwrap_err());
        assert!(
            err.contains("camera_zoom_rules[0]") && err.contains("81-*"),
            "{err}"
        );
    }

    #[test]
    fn bad_values_are_refused() {
        for bad in [
            "[timeline]\nfusion = \"biggest\"",
            "[timeline]\nliving_window = 2",
            "[timeline]\ndeath_penalty = -1",
            "[timeline]\ndeath_penalty = nan",
            "[inference]\nworkers = 0",
            "[inference]\nworkers = 1000000",
            "[inference]\nintra_threads = 1000000",
            "[inference]\nbatch_size = 0",
            "[inference]\nmax_attempts = 0",
            "[watch]\nstable_secs = -1.0",
            "[watch]\nstable_secs = nan",
            "[watch]\nstable_secs = inf",
            "[watch]\npoll_ms = 0",
            "[timeline]\nsession_gap_minutes = nan",
            "[timeline]\nsession_gap_minutes = 0",
            "[feed]\nkeep_days = -1",
            "[groups]\npattern = \"^(?P<genotype>.+)$\"\nby = [\"treatment\"]",
            "[[names.patterns]]\nname = \"x\"\nregex = \"(?P<plant>.*)\"",
            "[[timeline.zones]]\nname = \"h2\"\nplants = \"(\"",
            "[[timeline.zones]]\nname = \"h2\"\nplants = \"^2\"\n[[timeline.zones]]\nname = \"h2\"\nplants = \"^3\"",
            "[[timeline.zones]]\nname = \"h2\"",
            "[inference]\ncamera_zoom = 9",
            "[inference]\ncamera_zoom = \"guess\"",
            "[[inference.camera_zoom_rules]]\nfiles = \"81-*\"\ncamera_zoom = 0.1",
            "[[inference.camera_zoom_rules]]\nfiles = \"\"\ncamera_zoom = 2",
        ] {
            let text = format!("drop_dir = \"/d\"\ndatabase = \"/db\"\n{bad}\n");
            assert!(Config::parse(&text).is_err(), "accepted: {bad}");
        }
    }

    #[test]
    fn empty_paths_and_out_of_range_numbers_are_named_in_the_error() {
        let err = Config::parse("drop_dir = \"\"\ndatabase = \"/db\"\n")
            .unwrap_err()
            .to_string();
        assert!(err.contains("drop_dir must name a path"), "{err}");
        let err = Config::parse("drop_dir = \"/d\"\ndatabase = \"\"\n")
            .unwrap_err()
            .to_string();
        assert!(err.contains("database must name a path"), "{err}");
        let text = "drop_dir = \"/d\"\ndatabase = \"/db\"\n[inference]\nworkers = 1000000\n";
        let err = Config::parse(text).unwrap_err().to_string();
        assert!(
            err.contains("inference.workers must lie in 1..=256, not 1000000"),
            "{err}"
        );
        let text = "drop_dir = \"/d\"\ndatabase = \"/db\"\n[watch]\nstable_secs = -1.0\n";
        let err = Config::parse(text).unwrap_err().to_string();
        assert!(err.contains("watch.stable_secs"), "{err}");
        // The limits leave every shipped default and sample configuration valid.
        assert!(Config::parse("drop_dir = \"/d\"\ndatabase = \"/db\"\n").is_ok());
    }

    #[test]
    fn relative_paths_follow_the_config_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("phyllo.toml");
        std::fs::write(
            &path,
            "drop_dir = \"drop\"\ndatabase = \"/abs/db.sqlite\"\n[inference]\nmodel = \"m.onnx\"\n",
        )
        .unwrap();
        let cfg = Config::load(&path).unwrap();
        assert_eq!(cfg.drop_dir, dir.path().join("drop"));
        assert_eq!(cfg.database, PathBuf::from("/abs/db.sqlite"));
        assert_eq!(cfg.inference.model, Some(dir.path().join("m.onnx")));
        let err = format!(
            "{:#}",
            Config::load(&dir.path().join("missing.toml")).unwrap_err()
        );
        assert!(err.contains("missing.toml"), "{err}");
    }

    #[test]
    fn the_services_own_folders_may_not_lie_in_the_drop_directory() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir(dir.path().join("drop")).unwrap();
        std::os::unix::fs::symlink(dir.path().join("drop"), dir.path().join("link")).unwrap();
        let path = dir.path().join("phyllo.toml");
        let load = |extra: &str| {
            std::fs::write(&path, format!("drop_dir = \"drop\"\n{extra}")).unwrap();
            Config::load(&path).map_err(|e| format!("{e:#}"))
        };
        assert!(load("database = \"state/db.sqlite\"\n").is_ok());
        for (extra, what) in [
            ("database = \"drop/state/db.sqlite\"\n", "the database"),
            (
                "database = \"s/db.sqlite\"\n[export]\ndir = \"drop\"\n",
                "[export] dir",
            ),
            (
                "database = \"s/db.sqlite\"\n[export]\ndir = \"link/out\"\n",
                "[export] dir",
            ),
            (
                "database = \"s/db.sqlite\"\n[backup]\ndir = \"s/../drop/b\"\n",
                "[backup] dir",
            ),
        ] {
            let err = load(extra).unwrap_err();
            assert!(
                err.contains(what)
                    && err.contains("inside the drop directory")
                    && err.contains("phyllo.toml"),
                "{extra}: {err}"
            );
        }
    }

    /// The example config parses and documents every key the code knows.
    #[test]
    fn example_config_documents_every_key() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../systemd/phyllo.toml.example");
        let text = std::fs::read_to_string(&path).unwrap();
        let cfg = Config::parse(&text).unwrap();
        assert_eq!(cfg.drop_dir, PathBuf::from("/srv/phenotyping/drop"));
        // Out of the box it groups the facility's plants by genotype and
        // treatment, not each plant alone (issue 56 item 5).
        let groups = cfg.rules().groups.as_ref().expect("the example sets [groups]");
        assert_eq!(
            groups.group_of("402-348-N276-WW-1"),
            Some(vec!["N276".to_string(), "WW".to_string()])
        );
        assert_eq!(
            groups.group_of("402-349-N276-WW-2"),
            groups.group_of("402-348-N276-WW-1")
        );
        let keys = [
            "drop_dir",
            "database",
            "[watch]",
            "extensions",
            "ignore_hidden",
            "stable_secs",
            "settle_ms",
            "poll_ms",
            "rescan_secs",
            "quiet_hours",
            "skip_top_views",
            "[names]",
            "presets",
            "[[names.patterns]]",
            "regex",
            "[inference]",
            "model",
            "ort_lib",
            "workers",
            "intra_threads",
            "batch_size",
            "queue_capacity",
            "max_attempts",
            "zoom_plant_height",
            "flip",
            "camera_zoom",
            "[[inference.camera_zoom_rules]]",
            "files",
            "[inference.top_views]",
            "center_threshold",
            "nms_kernel",
            "[timeline]",
            "fusion",
            "session_gap_minutes",
            "living_window",
            "death_penalty",
            "base_temp_c",
            "[[timeline.zones]]",
            "plants",
            "[export]",
            "dir",
            "plots",
            "plot_axis",
            "[feed]",
            "keep_days",
            "[backup]",
            "keep",
            "keep_monthly",
            "[groups]",
            "pattern",
            "by",
            "block",
            "[import]",
        ];
        for k in keys {
            assert!(text.contains(k), "example config does not mention {k}");
        }
    }
}
