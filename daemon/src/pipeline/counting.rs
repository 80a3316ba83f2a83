//! The boundary between the daemon and the model: anything that turns image
//! bytes into a leaf count. The service holds an `Arc<dyn LeafCounter>`; in
//! production it is `phyllo_inference::Counter`.

use std::path::Path;

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
    /// Counts the leaves in an image whose bytes were already read. `name` is
    /// for messages and to recognise the format.
    fn count(&self, name: &Path, bytes: &[u8]) -> Result<CountRecord, CountError>;
    /// Identifies the model, stored with every observation.
    fn model_id(&self) -> String;
    /// The settings its counts are made with (JSON, as stored with each
    /// observation); `Null` for a counter that has none to report.
    fn settings(&self) -> serde_json::Value {
        serde_json::Value::Null
    }
}

/// The inference core's settings from `[inference]`.
pub fn counter_config(cfg: &crate::config::InferenceConfig) -> phyllo_inference::CounterConfig {
    phyllo_inference::CounterConfig {
        model: cfg.model.clone(),
        ort_lib: cfg.ort_lib.clone(),
        intra_threads: cfg.intra_threads,
        batch_size: cfg.batch_size,
        zoom_plant_height: cfg.zoom_plant_height,
        flip: cfg.flip,
        camera_zoom: cfg.camera_zoom,
        camera_zoom_rules: cfg.camera_zoom_rules.clone(),
        top_views: cfg.top_views.clone(),
        ..phyllo_inference::CounterConfig::default()
    }
}

/// Builds the production counter (ONNX Runtime) from `[inference]`.
pub fn onnx_counter(cfg: &crate::config::InferenceConfig) -> anyhow::Result<std::sync::Arc<dyn LeafCounter>> {
    let counter = phyllo_inference::Counter::new(counter_config(cfg))?;
    Ok(std::sync::Arc::new(counter))
}

impl LeafCounter for phyllo_inference::Counter {
    fn count(&self, name: &Path, bytes: &[u8]) -> Result<CountRecord, CountError> {
        use phyllo_inference::InferenceError as E;
        match self.count_bytes(name, bytes) {
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
                model_id: self.model_id_for(name),
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
        phyllo_inference::Counter::model_id(self)
    }

    fn settings(&self) -> serde_json::Value {
        counting_settings(self.config())
    }
}

/// What a count depends on besides the model and the image, as stored with
/// each observation.
fn counting_settings(config: &phyllo_inference::CounterConfig) -> serde_json::Value {
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
        "camera_zoom_rules": config.camera_zoom_rules,
        "postprocess": config.postprocess,
        "top_views": config.top_views,
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
        let text = counting_settings(&config).to_string();
        assert!(text.contains("\"scale\":0.3,"), "{text}");
        assert!(!text.contains("0000000"), "{text}");
    }
}
