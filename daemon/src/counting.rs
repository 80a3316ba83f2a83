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
}
