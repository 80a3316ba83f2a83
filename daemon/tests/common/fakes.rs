//! Fake [`LeafCounter`]s: the service run in-process without the model or
//! ONNX Runtime. (The fakes in `src/` unit tests — `ops/recount.rs`,
//! `pipeline/supervise.rs` — stay beside their tests.) A change to the
//! trait's signature changes this file only.

use std::path::Path;
use std::time::Duration;

use phyllo::counting::{CountError, LeafCounter};
use phyllo::domain::names::View;
use phyllo::store::CountRecord;

/// Reads "leaves=N ... END" files. Anything else (a partial file included) is an
/// undecodable image, which the service must record as failed.
pub struct TextCounter;

impl TextCounter {
    /// A complete "image" that [`TextCounter`] counts as `n` leaves (about
    /// 2 kB: long enough to be written slowly, in pieces).
    pub fn body(n: u32) -> String {
        format!("leaves={n} {}END\n", "x".repeat(2000))
    }
}

impl LeafCounter for TextCounter {
    fn count(&self, name: &Path, _: &View, bytes: &[u8]) -> Result<CountRecord, CountError> {
        let text = String::from_utf8_lossy(bytes);
        let n = text
            .strip_prefix("leaves=")
            .and_then(|r| r.split_whitespace().next())
            .and_then(|n| n.parse::<u32>().ok())
            .filter(|_| text.trim_end().ends_with("END"));
        match n {
            Some(n) => Ok(CountRecord {
                leaf_count: n,
                instances: serde_json::json!([]),
                timing: serde_json::json!({"total": 1.0}),
                ms_total: 1.0,
                model_id: "text-counter".into(),
                settings: serde_json::Value::Null,
            }),
            None => Err(CountError {
                message: format!("image {}: not a complete image", name.display()),
                retry: false,
            }),
        }
    }

    fn model_id(&self) -> String {
        "text-counter".into()
    }
}

/// Counts like [`TextCounter`] but takes its time, like a real model on a slow CPU.
pub struct SlowCounter(pub Duration);

impl LeafCounter for SlowCounter {
    fn count(&self, name: &Path, view: &View, bytes: &[u8]) -> Result<CountRecord, CountError> {
        std::thread::sleep(self.0);
        TextCounter.count(name, view, bytes)
    }

    fn model_id(&self) -> String {
        "slow-text-counter".into()
    }
}
