//! The boundary between the daemon and the model: anything that turns image
//! bytes into a leaf count. A layer of its own, below the service
//! (`pipeline`) and the operator commands (`ops::recount`) that both count. The service holds an `Arc<dyn LeafCounter>`; in
//! production it is an [`OnnxCounter`], `phyllo_inference::Counter` with the
//! rules that tell it what each image is ([`ImageRules`]): the caller hands
//! in the view it parsed from the name, once, and the model gets the facts.

use std::path::Path;

use phyllo_inference::ImageFacts;

use crate::config::InferenceConfig;
use crate::domain::image_facts::{CameraZoomRule, ImageRules, TopViewsConfig};
use crate::domain::names::View;
use crate::store::CountRecord;

/// Why an image could not be counted.
#[derive(Debug, Clone)]
pub struct CountError {
    /// Message naming the file and the problem.
    pub message: String,
    /// True if trying again later may succeed (runtime trouble), false if the
    /// data itself is bad (undecodable image) and retrying is pointless.
    pub retry: bool,
}

/// Counts leaves. Blocking and CPU-heavy: call it from worker threads only.
pub trait LeafCounter: Send + Sync {
    /// Counts the leaves in an image whose bytes were already read and whose
    /// name `[names]` read as `view`. `name` is for messages and for the
    /// station rules on the file name; the format is told by the bytes.
    fn count(&self, name: &Path, view: &View, bytes: &[u8]) -> Result<CountRecord, CountError>;
    /// Identifies the model, stored with every observation.
    fn model_id(&self) -> String;
    /// The settings its counts are made with (JSON, as stored with each
    /// observation); `Null` for a counter that has none to report.
    fn settings(&self) -> serde_json::Value {
        serde_json::Value::Null
    }
}

/// What the service counts with: the inference core's settings and the
/// daemon's rules that say what each image is.
#[derive(Debug, Clone)]
pub struct CountingConfig {
    /// The inference core's settings.
    pub counter: phyllo_inference::CounterConfig,
    /// `[[inference.camera_zoom_rules]]`: zooms pinned by file-name pattern.
    pub camera_zoom_rules: Vec<CameraZoomRule>,
    /// `[inference.top_views]`, its deprecated `files` included.
    pub top_views: TopViewsConfig,
}

impl CountingConfig {
    /// The rules that turn a parsed name into the model's [`ImageFacts`].
    pub fn image_rules(&self) -> ImageRules<'_> {
        ImageRules::new(&self.camera_zoom_rules, &self.top_views)
    }
}

/// The counting settings from `[inference]`.
pub fn counter_config(cfg: &InferenceConfig) -> CountingConfig {
    CountingConfig {
        counter: phyllo_inference::CounterConfig {
            model: cfg.model.clone(),
            ort_lib: cfg.ort_lib.clone(),
            intra_threads: cfg.intra_threads,
            batch_size: cfg.batch_size,
            zoom_plant_height: cfg.zoom_plant_height,
            flip: cfg.flip,
            camera_zoom: cfg.camera_zoom,
            top_views: cfg.top_views.counting(),
            ..phyllo_inference::CounterConfig::default()
        },
        camera_zoom_rules: cfg.camera_zoom_rules.clone(),
        top_views: cfg.top_views.clone(),
    }
}

/// Builds the production counter (ONNX Runtime) from `[inference]`.
pub fn onnx_counter(cfg: &InferenceConfig) -> anyhow::Result<std::sync::Arc<dyn LeafCounter>> {
    Ok(std::sync::Arc::new(OnnxCounter::new(counter_config(cfg))?))
}

/// The production counter: the inference core and the rules that say what
/// each image is.
pub struct OnnxCounter {
    counter: phyllo_inference::Counter,
    config: CountingConfig,
}

impl OnnxCounter {
    /// Loads ONNX Runtime and the models `config` names.
    pub fn new(config: CountingConfig) -> anyhow::Result<Self> {
        let counter = phyllo_inference::Counter::new(config.counter.clone())?;
        Ok(Self { counter, config })
    }

    /// What the model is told about the image at `name`, read as `view`.
    pub fn facts(&self, name: &Path, view: &View) -> ImageFacts {
        self.config.image_rules().facts(name, view)
    }

    /// The inference core, for overlays and the like.
    pub fn inner(&self) -> &phyllo_inference::Counter {
        &self.counter
    }
}

impl LeafCounter for OnnxCounter {
    fn count(&self, name: &Path, view: &View, bytes: &[u8]) -> Result<CountRecord, CountError> {
        use phyllo_inference::InferenceError as E;
        let facts = self.facts(name, view);
        match self.counter.count_bytes(name, &facts, bytes) {
            Ok(r) => Ok(CountRecord {
                leaf_count: r.leaf_count,
                instances: serde_json::to_value(&r.instances).unwrap_or_default(),
                timing: serde_json::json!({
                    "ms": r.ms,
                    "tiles": r.tiles,
                    "image_size": r.image_size,
                    "region": r.region,
                    "scale": r.scale,
                    "camera": r.camera,
                }),
                ms_total: r.ms.total,
                model_id: self.counter.model_id_for(facts.view),
                settings: LeafCounter::settings(self),
            }),
            Err(e) => {
                // Bad image data will fail the same way every time; runtime trouble may pass.
                let retry = !matches!(e, E::Image { .. });
                Err(CountError {
                    message: e.to_string(),
                    retry,
                })
            }
        }
    }

    fn model_id(&self) -> String {
        self.counter.model_id()
    }

    fn settings(&self) -> serde_json::Value {
        counting_settings(&self.config)
    }
}

/// What a count depends on besides the model and the image, as stored with
/// each observation.
fn counting_settings(counting: &CountingConfig) -> serde_json::Value {
    let config = &counting.counter;
    // The contract's values where the configuration leaves them open, so a
    // later contract change shows too.
    let zoom = phyllo_inference::zoom::Zoom::from_contract(phyllo_contract::Contract::embedded());
    let mut settings = serde_json::json!({
        "zoom_plant_height": config.zoom_plant_height.unwrap_or(zoom.plant_height),
        "max_zoom": config.max_zoom.unwrap_or(zoom.max),
        "zoom_height_measure": config.zoom_height_measure,
        "flip": config.flip,
        "region": config.region,
        "scale": config.scale,
        "camera_zoom": config.camera_zoom,
        "camera_zoom_rules": counting.camera_zoom_rules,
        "postprocess": config.postprocess,
        "top_views": counting.top_views,
    });
    shorten_f32(&mut settings);
    settings
}

/// Writes numbers that came from `f32` settings as their shortest decimal
/// (`0.3`, not `0.30000001192092896`): `json!` widens them to `f64`, and the
/// stored settings reach `images.csv` and `phyllo status`.
fn shorten_f32(v: &mut serde_json::Value) {
    match v {
        serde_json::Value::Number(n) if !(n.is_i64() || n.is_u64()) => {
            let x = n.as_f64().unwrap_or_default();
            let narrow = x as f32;
            if f64::from(narrow) == x {
                if let Some(short) = narrow
                    .to_string()
                    .parse::<f64>()
                    .ok()
                    .and_then(serde_json::Number::from_f64)
                {
                    *n = short;
                }
            }
        }
        serde_json::Value::Array(items) => items.iter_mut().for_each(shorten_f32),
        serde_json::Value::Object(map) => map.values_mut().for_each(shorten_f32),
        _ => {}
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn settings_read_as_the_config_wrote_them() {
        let config = phyllo_inference::CounterConfig {
            scale: Some(0.3),
            ..phyllo_inference::CounterConfig::default()
        };
        let counting = CountingConfig {
            counter: config,
            camera_zoom_rules: Vec::new(),
            top_views: TopViewsConfig::default(),
        };
        let text = counting_settings(&counting).to_string();
        assert!(text.contains("\"scale\":0.3,"), "{text}");
        assert!(!text.contains("0000000"), "{text}");
    }

    /// The rules that moved out of the inference core (issue 55) are stored
    /// with each observation as they were before.
    #[test]
    fn image_rules_are_stored_as_before() {
        let cfg = crate::config::Config::parse(
            "drop_dir = \"/d\"\ndatabase = \"/db\"\n[[inference.camera_zoom_rules]]\nfiles = \"81-*\"\ncamera_zoom = 2\n",
        )
        .unwrap();
        let text = counting_settings(&counter_config(&cfg.inference)).to_string();
        for part in [
            r#""camera_zoom_rules":[{"camera_zoom":2.0,"files":"81-*"}]"#,
            r#""top_views":{"center_threshold":null,"files":["*_TV_*","*_top.*"],"model":"default","nms_kernel":null}"#,
        ] {
            assert!(text.contains(part), "{part} not in {text}");
        }
    }
}
