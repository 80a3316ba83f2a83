//! Loading a panoptic ONNX model and checking it against the contract.

use std::path::{Path, PathBuf};
use std::sync::Mutex;

use ndarray::{Array4, ArrayView4, Ix4};
use ort::session::Session;
use ort::value::{TensorRef, ValueType};
use phyllo_contract::{Contract, NUM_CLASSES};
use serde::Serialize;
use sha2::{Digest, Sha256};

use crate::error::InferenceError;
use crate::stitch::TileOutputs;

/// What a loaded model says about itself.
#[derive(Debug, Clone, Serialize)]
pub struct ModelInfo {
    /// Path it was loaded from.
    pub path: PathBuf,
    /// `phyllo.model_name` from its metadata (file stem if absent).
    pub name: String,
    /// Whether `phyllo.trained` says "true". Untrained models run the
    /// machinery end to end, but their counts mean nothing.
    pub trained: bool,
    /// `phyllo.training_data` from its metadata.
    pub training_data: String,
    /// First 12 hex digits of the file's SHA-256.
    pub sha256_prefix: String,
    /// Whether the model has the contract's optional leaf-tip heatmap output
    /// (`[outputs] tip`). Without it every count rule counts centres.
    pub has_tips: bool,
}

impl ModelInfo {
    /// Identifier stored with every observation: `name@sha256-prefix`.
    pub fn id(&self) -> String {
        format!("{}@{}", self.name, self.sha256_prefix)
    }
}

/// A model ready to run tiles, shareable across threads.
pub struct Model {
    session: Mutex<Session>,
    info: ModelInfo,
    contract: &'static Contract,
}

/// Session options for [`Model::load`].
#[derive(Debug, Clone, Copy)]
pub struct ModelOptions {
    /// ONNX Runtime intra-op threads (0: ONNX Runtime's default, one per core).
    pub intra_threads: usize,
    /// Let idle ONNX Runtime threads spin. Off by default: spinning threads
    /// steal the cores that decode the next image (measured: 25 ms per tile
    /// without spinning, 54 ms with it, on 2 shared cores).
    pub spinning: bool,
}

impl Model {
    /// Loads `path`, refusing it with a message naming every difference if it
    /// does not follow the contract.
    pub fn load(
        env: &ort::environment::Environment,
        path: &Path,
        options: ModelOptions,
    ) -> Result<Self, InferenceError> {
        let contract = Contract::embedded();
        let bytes =
            std::fs::read(path).map_err(|e| InferenceError::model(path, format!("cannot read: {e}")))?;
        if bytes.is_empty() {
            return Err(InferenceError::model(path, "file is empty"));
        }
        let sha = Sha256::digest(&bytes);
        let sha256_prefix: String = sha.iter().take(6).map(|b| format!("{b:02x}")).collect();
        let mut builder = Session::builder(env).map_err(|e| InferenceError::model(path, e))?;
        if options.intra_threads > 0 {
            builder = builder
                .with_intra_threads(options.intra_threads)
                .map_err(|e| InferenceError::model(path, e))?;
        }
        builder = builder
            .with_intra_op_spinning(options.spinning)
            .map_err(|e| InferenceError::model(path, e))?;
        let session = builder
            .commit_from_memory(&bytes)
            .map_err(|e| InferenceError::model(path, format!("not a loadable ONNX model: {e}")))?;
        let meta = session.metadata().map_err(|e| InferenceError::model(path, e))?;
        let key = |k: &str| meta.custom(k);
        let mut problems = Vec::new();
        match key(&contract.metadata.contract_version) {
            Some(v) if v.trim() == contract.version.to_string() => {}
            Some(v) => problems.push(format!(
                "metadata {} is {v:?}, this build needs {:?}",
                contract.metadata.contract_version, contract.version
            )),
            None => problems.push(format!(
                "metadata has no {} key",
                contract.metadata.contract_version
            )),
        }
        let (io_problems, has_tips) = check_io(&session, contract);
        problems.extend(io_problems);
        if !problems.is_empty() {
            return Err(InferenceError::model(
                path,
                format!(
                    "does not follow phyllo contract v{}: {} (the contract is models/contract.toml; \
                     export the model with models/phyllo_train/export.py, which writes it in)",
                    contract.version,
                    problems.join("; ")
                ),
            ));
        }
        let name = key(&contract.metadata.model_name).unwrap_or_else(|| {
            path.file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default()
        });
        let trained = key(&contract.metadata.trained).is_some_and(|v| v.trim() == "true");
        let training_data = key(&contract.metadata.training_data).unwrap_or_default();
        drop(meta);
        let info = ModelInfo {
            path: path.to_path_buf(),
            name,
            trained,
            training_data,
            sha256_prefix,
            has_tips,
        };
        Ok(Self {
            session: Mutex::new(session),
            info,
            contract,
        })
    }

    /// What the model says about itself.
    pub fn info(&self) -> &ModelInfo {
        &self.info
    }

    /// Runs one batch of tiles `[n, 3, tile, tile]`.
    pub fn run(&self, batch: ArrayView4<'_, f32>) -> Result<TileOutputs, InferenceError> {
        let c = self.contract;
        let input =
            TensorRef::from_array_view(batch).map_err(|e| InferenceError::Inference(e.to_string()))?;
        let mut session = self.session.lock().unwrap_or_else(|e| e.into_inner());
        let outputs = session
            .run(ort::inputs![c.input.name.as_str() => input])
            .map_err(|e| InferenceError::Inference(e.to_string()))?;
        let take = |name: &str, channels: usize| -> Result<Array4<f32>, InferenceError> {
            let v = outputs
                .get(name)
                .ok_or_else(|| InferenceError::Inference(format!("model produced no output {name:?}")))?;
            let arr = v
                .try_extract_array::<f32>()
                .map_err(|e| InferenceError::Inference(format!("output {name:?}: {e}")))?
                .into_dimensionality::<Ix4>()
                .map_err(|e| InferenceError::Inference(format!("output {name:?} is not 4-D: {e}")))?;
            let expect = (batch.dim().0, channels, batch.dim().2 / c.outputs.stride as usize);
            let got = arr.dim();
            if (got.0, got.1, got.2) != expect || got.2 != got.3 {
                return Err(InferenceError::Inference(format!(
                    "output {name:?} has shape {got:?}, contract expects [{}, {}, {}, {}]",
                    expect.0, expect.1, expect.2, expect.2
                )));
            }
            Ok(arr.to_owned())
        };
        let tip = if self.info.has_tips {
            Some(take(&c.outputs.tip, 1)?)
        } else {
            None
        };
        Ok(TileOutputs {
            semantic: take(&c.outputs.semantic, NUM_CLASSES)?,
            center: take(&c.outputs.center, 1)?,
            offset: take(&c.outputs.offset, 2)?,
            tip,
        })
    }
}

/// Differences between the session's inputs/outputs and the contract's, and
/// whether the model has the optional tip output.
fn check_io(session: &Session, c: &Contract) -> (Vec<String>, bool) {
    let mut problems = Vec::new();
    let dims = |t: &ValueType| -> Option<Vec<i64>> {
        match t {
            ValueType::Tensor { ty, shape, .. } if *ty == ort::value::TensorElementType::Float32 => {
                Some(shape.iter().copied().collect())
            }
            _ => None,
        }
    };
    let inputs = session.inputs();
    if inputs.len() != 1 || inputs[0].name() != c.input.name {
        problems.push(format!(
            "inputs are {:?}, contract expects one input {:?}",
            inputs.iter().map(|i| i.name()).collect::<Vec<_>>(),
            c.input.name
        ));
    } else {
        match dims(inputs[0].dtype()) {
            Some(d) if d.len() == 4 && (d[1] == 3 || d[1] < 0) => {}
            other => problems.push(format!(
                "input {:?} is {other:?}, contract expects float32 [N, 3, H, W]",
                c.input.name
            )),
        }
    }
    let outputs: Vec<(&str, Option<Vec<i64>>)> = session
        .outputs()
        .iter()
        .map(|o| (o.name(), dims(o.dtype())))
        .collect();
    let has_tips = check_outputs(&outputs, c, &mut problems);
    (problems, has_tips)
}

/// Checks the model's outputs, each a name and its float32 dimensions
/// (`None`: not a float32 tensor), against the contract's, adding the
/// differences to `problems`. Returns whether the optional tip output is
/// there: a model without it counts by centres, but one that has it must
/// give it the contract's shape.
fn check_outputs(outputs: &[(&str, Option<Vec<i64>>)], c: &Contract, problems: &mut Vec<String>) -> bool {
    let find = |name: &str| outputs.iter().find(|(n, _)| *n == name).map(|(_, d)| d);
    let fits =
        |d: &Option<Vec<i64>>, ch: i64| matches!(d, Some(d) if d.len() == 4 && (d[1] == ch || d[1] < 0));
    for (name, ch) in [
        (&c.outputs.semantic, NUM_CLASSES as i64),
        (&c.outputs.center, 1),
        (&c.outputs.offset, 2),
    ] {
        match find(name) {
            None => problems.push(format!("no output named {name:?}")),
            Some(d) if fits(d, ch) => {}
            Some(other) => problems.push(format!(
                "output {name:?} is {other:?}, contract expects float32 [N, {ch}, H, W]"
            )),
        }
    }
    let tip = &c.outputs.tip;
    match find(tip) {
        None => false,
        Some(d) => {
            if !fits(d, 1) {
                problems.push(format!(
                    "optional output {tip:?} is {d:?}, contract expects float32 [N, 1, H, W] (a leaf-tip heatmap)"
                ));
            }
            true
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check(outputs: &[(&str, Option<Vec<i64>>)]) -> (Vec<String>, bool) {
        let mut problems = Vec::new();
        let has_tips = check_outputs(outputs, Contract::embedded(), &mut problems);
        (problems, has_tips)
    }

    const BASE: [(&str, [i64; 4]); 3] = [
        ("semantic", [-1, 4, -1, -1]),
        ("center", [-1, 1, -1, -1]),
        ("offset", [-1, 2, -1, -1]),
    ];

    fn outputs(extra: Option<Option<Vec<i64>>>) -> Vec<(&'static str, Option<Vec<i64>>)> {
        let mut v: Vec<_> = BASE.iter().map(|(n, d)| (*n, Some(d.to_vec()))).collect();
        if let Some(tip) = extra {
            v.push(("tip", tip));
        }
        v
    }

    #[test]
    fn the_tip_output_is_optional() {
        assert_eq!(check(&outputs(None)), (vec![], false));
        assert_eq!(check(&outputs(Some(Some(vec![-1, 1, -1, -1])))), (vec![], true));
        assert_eq!(check(&outputs(Some(Some(vec![2, 1, 256, 256])))), (vec![], true));
    }

    #[test]
    fn a_tip_output_of_the_wrong_shape_or_type_is_a_problem() {
        for bad in [Some(vec![-1, 2, -1, -1]), Some(vec![-1, -1, -1]), None] {
            let (problems, has_tips) = check(&outputs(Some(bad.clone())));
            assert!(has_tips);
            assert_eq!(problems.len(), 1, "{bad:?}: {problems:?}");
            assert!(
                problems[0].contains("\"tip\"") && problems[0].contains("[N, 1, H, W]"),
                "{}",
                problems[0]
            );
        }
    }

    #[test]
    fn missing_required_outputs_are_still_problems() {
        let (problems, _) = check(&[("semantic", Some(vec![-1, 4, -1, -1]))]);
        assert_eq!(
            problems,
            vec!["no output named \"center\"", "no output named \"offset\""]
        );
    }
}
