//! The inference pipeline: image bytes in, leaf count out.
//!
//! What the image is (side or top view, the zoom its station pins) comes in
//! as [`ImageFacts`] from the caller; nothing here reads a file name.

use std::path::{Path, PathBuf};
use std::time::Instant;

use image::RgbImage;
use phyllo_contract::Contract;
use serde::{Deserialize, Serialize};

use crate::attachment::keep_attached;
use crate::camera_scale::{self, CameraZoom};
use crate::decode::{decode_rgb, DecodeLimits};
use crate::error::InferenceError;
use crate::flip;
use crate::image::{ImageFacts, View};
use crate::model::{Model, ModelInfo, ModelOptions};
pub use crate::model_path::{default_model_path, MODEL_ENV};
use crate::panoptic::Panoptic;
use crate::pieces::{drop_far_specks, split_pieces};
use crate::postprocess::{panoptic, PostprocessParams};
use crate::region::RegionMode;
use crate::result::{CountResult, Instance, StageTimings};
use crate::runtime;
use crate::stitch::{stitch, TileOutputs};
use crate::tiling::{batch_tensor, prepare, Canvas};
use crate::tips::CountRule;
use crate::top_view::TopViewConfig;
use crate::zoom::{instances_height, plant_height, HeightMeasure, Zoom};

/// Slack around the plant's box, in model pixels, within which instance
/// centres are still taken as plant.
const PLANT_MARGIN: i64 = 16;

/// Everything the pipeline can be told.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CounterConfig {
    /// Model file; `None` picks the default (see [`default_model_path`]).
    pub model: Option<PathBuf>,
    /// ONNX Runtime shared library; `None` searches (see [`crate::runtime`]).
    pub ort_lib: Option<PathBuf>,
    /// ONNX Runtime intra-op threads (0: one per core).
    pub intra_threads: usize,
    /// Let idle ONNX Runtime threads spin (faster only on otherwise idle cores).
    pub ort_spinning: bool,
    /// Tiles per ONNX Runtime call.
    pub batch_size: usize,
    /// How the plant's region is found.
    pub region: RegionMode,
    /// Model pixels per image pixel; `None` applies the contract's scale rule
    /// (frames to the contract's frame height, crops to its crop size). Set
    /// 1.0 for images already at the contract's scale, such as phyllo-gen
    /// dataset crops.
    pub scale: Option<f32>,
    /// The side camera's zoom relative to the contract's: measured on the
    /// chamber's back panel (the default), the contract's, or pinned. An
    /// image whose [`ImageFacts`] pin a zoom is counted at that one instead.
    pub camera_zoom: CameraZoom,
    /// Plant height small plants are enlarged to, in model pixels (0: never
    /// enlarge); `None` takes the contract's `zoom_plant_height`.
    pub zoom_plant_height: Option<u32>,
    /// Largest enlargement of a small plant; `None` takes the contract's
    /// `max_zoom`.
    pub max_zoom: Option<f32>,
    /// Which of the first pass's instances the small-plant rule measures.
    pub zoom_height_measure: HeightMeasure,
    /// Also run every tile mirrored and average the two (twice the model
    /// time).
    pub flip: bool,
    /// Post-processing parameters.
    pub postprocess: PostprocessParams,
    /// Which model counts the top views, and how.
    pub top_views: TopViewConfig,
    /// Decoder limits.
    pub limits: DecodeLimits,
}

impl Default for CounterConfig {
    fn default() -> Self {
        Self {
            model: None,
            ort_lib: None,
            intra_threads: 0,
            ort_spinning: false,
            batch_size: 4,
            region: RegionMode::Auto,
            scale: None,
            camera_zoom: CameraZoom::default(),
            zoom_plant_height: None,
            max_zoom: None,
            zoom_height_measure: HeightMeasure::default(),
            flip: false,
            postprocess: PostprocessParams::default(),
            top_views: TopViewConfig::default(),
            limits: DecodeLimits::default(),
        }
    }
}

/// Everything counting one image produced, for overlays and evaluation.
#[derive(Debug, Clone)]
pub struct Analysis {
    /// The count and instances in original-image pixels.
    pub result: CountResult,
    /// The panoptic segmentation of the canvas, in output pixels.
    pub panoptic: Panoptic,
    /// The canvas and its mapping back to the original image.
    pub canvas: Canvas,
}

/// Counts leaves. Safe to share between threads: ONNX Runtime calls are
/// serialised inside (each already uses every core it is given).
pub struct Counter {
    model: Model,
    /// The top-view model and the post-processing it counts with.
    top: Option<(Model, PostprocessParams)>,
    config: CounterConfig,
    contract: &'static Contract,
}

/// The model that counts one image and its post-processing.
#[derive(Clone, Copy)]
struct Net<'a> {
    model: &'a Model,
    postprocess: &'a PostprocessParams,
}

impl Counter {
    /// Loads ONNX Runtime and the model.
    pub fn new(config: CounterConfig) -> Result<Self, InferenceError> {
        let env = runtime::environment(config.ort_lib.as_deref())?;
        let model_path = config.model.clone().unwrap_or_else(default_model_path);
        let options = ModelOptions {
            intra_threads: config.intra_threads,
            spinning: config.ort_spinning,
        };
        let model = Model::load(env, &model_path, options)?;
        let side_model_chosen = config.model.is_some() || crate::model_path::side_model_from_env();
        let top = match config.top_views.model_path(side_model_chosen) {
            Some(path) => {
                let postprocess = PostprocessParams {
                    center_threshold: config.top_views.center_threshold(),
                    nms_kernel: config.top_views.nms_kernel(),
                    ..config.postprocess
                };
                Some((Model::load(env, &path, options)?, postprocess))
            }
            None => None,
        };
        Ok(Self {
            model,
            top,
            config,
            contract: Contract::embedded(),
        })
    }

    /// What the (side-view) model says about itself.
    pub fn model_info(&self) -> &ModelInfo {
        self.model.info()
    }

    /// What the top-view model says about itself, when there is one.
    pub fn top_model_info(&self) -> Option<&ModelInfo> {
        self.top.as_ref().map(|(m, _)| m.info())
    }

    /// `name@sha256-prefix` of the model; with a top-view model, both, as
    /// `side@sha+top@sha`.
    pub fn model_id(&self) -> String {
        match self.top_model_info() {
            Some(top) => format!("{}+{}", self.model.info().id(), top.id()),
            None => self.model.info().id(),
        }
    }

    /// `name@sha256-prefix` of the model that counts images seen from
    /// `view`, stored with each observation.
    pub fn model_id_for(&self, view: View) -> String {
        self.net_for(view).model.info().id()
    }

    /// Whether images seen from `view` are counted by the top-view model.
    pub fn counts_as_top_view(&self, view: View) -> bool {
        self.top_net_for(view).is_some()
    }

    fn net_for(&self, view: View) -> Net<'_> {
        self.top_net_for(view).unwrap_or_else(|| self.side_net())
    }

    fn top_net_for(&self, view: View) -> Option<Net<'_>> {
        let (model, postprocess) = self.top.as_ref()?;
        view.is_top().then_some(Net { model, postprocess })
    }

    fn side_net(&self) -> Net<'_> {
        Net {
            model: &self.model,
            postprocess: &self.config.postprocess,
        }
    }

    /// The rule its counts follow: the configured one with a model that has
    /// a tip output, [`CountRule::Centres`] without (see [`crate::tips`]).
    pub fn count_rule(&self) -> CountRule {
        if self.model.info().has_tips {
            self.config.postprocess.count_rule
        } else {
            CountRule::Centres
        }
    }

    /// The configuration this counter runs with.
    pub fn config(&self) -> &CounterConfig {
        &self.config
    }

    /// Reads and counts the image at `path`, which the caller says is
    /// `facts` (the path only names it in errors).
    pub fn count_path(&self, path: &Path, facts: &ImageFacts) -> Result<CountResult, InferenceError> {
        let bytes =
            std::fs::read(path).map_err(|e| InferenceError::image(path, format!("cannot read: {e}")))?;
        self.count_bytes(path, facts, &bytes)
    }

    /// Counts an image whose bytes the caller already read; `name` names it
    /// in errors, `facts` say which model counts it and at which zoom.
    pub fn count_bytes(
        &self,
        name: &Path,
        facts: &ImageFacts,
        bytes: &[u8],
    ) -> Result<CountResult, InferenceError> {
        self.analyse_bytes(name, facts, bytes).map(|a| a.result)
    }

    /// Decodes and analyses an image, keeping the intermediate results. The
    /// format is told by the bytes; `name` only names the image in errors.
    pub fn analyse_bytes(
        &self,
        name: &Path,
        facts: &ImageFacts,
        bytes: &[u8],
    ) -> Result<Analysis, InferenceError> {
        let t0 = Instant::now();
        let img = decode_rgb(name, bytes, &self.config.limits)?;
        let decode_ms = ms(t0);
        let zoom = facts.camera_zoom.unwrap_or(self.config.camera_zoom);
        let mut analysis = self.analyse_with(self.net_for(facts.view), &img, zoom)?;
        analysis.result.ms.decode = decode_ms;
        analysis.result.ms.total += decode_ms;
        Ok(analysis)
    }

    /// Analyses an already decoded side view with the configured camera zoom
    /// (a station's pinned zoom comes with [`ImageFacts`]: see
    /// [`Counter::analyse_bytes`]).
    pub fn analyse_image(&self, img: &RgbImage) -> Result<Analysis, InferenceError> {
        self.analyse_image_at(img, self.config.camera_zoom)
    }

    /// Analyses an already decoded side view taken with camera zoom
    /// `camera_zoom`.
    pub fn analyse_image_at(
        &self,
        img: &RgbImage,
        camera_zoom: CameraZoom,
    ) -> Result<Analysis, InferenceError> {
        self.analyse_with(self.side_net(), img, camera_zoom)
    }

    fn analyse_with(
        &self,
        net: Net<'_>,
        img: &RgbImage,
        camera_zoom: CameraZoom,
    ) -> Result<Analysis, InferenceError> {
        let c = self.contract;
        let mut zoom = Zoom::from_contract(c);
        if let Some(h) = self.config.zoom_plant_height {
            zoom.plant_height = h;
        }
        if let Some(m) = self.config.max_zoom {
            zoom.max = m;
        }
        let mut timings = StageTimings::default();
        let t0 = Instant::now();
        let camera = camera_scale::choose(c, img, self.config.scale, camera_zoom);
        timings.tile += ms(t0);
        let (mut canvas, mut pan) = self.pass(net, img, Some(camera.scale), &mut timings)?;
        let mut tiles = canvas.tiles.len() as u32;
        // A fixed region bounds the chamber, not the plant; only an
        // automatic one may be zoomed into.
        if self.config.region == RegionMode::Auto {
            let z = self.plant_height(&pan, &canvas).map_or(1.0, |h| zoom.factor(h));
            if z > 1.0 {
                (canvas, pan) = self.pass(net, img, Some(canvas.scale * z), &mut timings)?;
                tiles += canvas.tiles.len() as u32;
            }
        }
        let t = Instant::now();
        // Only once the scale is settled: specks would otherwise change the
        // plant's measured height and with it the enlargement.
        self.tidy(&mut pan, &canvas);
        let mut result = to_result(c, &pan, &canvas, img.dimensions(), net.postprocess);
        result.tiles = tiles;
        result.camera = Some(camera);
        timings.postprocess += ms(t);
        timings.total = timings.tile + timings.inference + timings.postprocess;
        result.ms = timings;
        Ok(Analysis {
            result,
            panoptic: pan,
            canvas,
        })
    }

    /// The first pass's plant height for the small-plant rule, in model
    /// pixels, by the configured [`HeightMeasure`].
    fn plant_height(&self, pan: &Panoptic, canvas: &Canvas) -> Option<u32> {
        let stride = self.contract.outputs.stride;
        match self.config.zoom_height_measure {
            HeightMeasure::All => instances_height(pan, stride),
            HeightMeasure::Plant => {
                let mut body = pan.clone();
                self.tidy(&mut body, canvas);
                let p = &self.config.postprocess;
                plant_height(&body, stride, p.split_min_area, p.speck_distance)
            }
        }
    }

    /// Takes from the leaves what is not theirs without changing the count:
    /// pixels outside the plant's box and specks far from their leaf's body.
    fn tidy(&self, pan: &mut Panoptic, canvas: &Canvas) {
        let p = &self.config.postprocess;
        if let Some(plant) = canvas.plant {
            clear_outside_plant(pan, plant, self.contract.outputs.stride);
        }
        drop_far_specks(pan, p.split_min_area, p.split_gap, p.speck_distance);
    }

    /// One pass through tiling, the model and post-processing at `scale`
    /// (or the contract's), adding its stage times to `timings`.
    fn pass(
        &self,
        net: Net<'_>,
        img: &RgbImage,
        scale: Option<f32>,
        timings: &mut StageTimings,
    ) -> Result<(Canvas, Panoptic), InferenceError> {
        let c = self.contract;
        let t0 = Instant::now();
        let canvas = prepare(c, img, self.config.region, scale);
        timings.tile += ms(t0);

        let t1 = Instant::now();
        let mut outputs: Option<TileOutputs> = None;
        for chunk in canvas.tiles.chunks(self.config.batch_size.max(1)) {
            let batch = batch_tensor(c, &canvas.image, chunk);
            let mut out = net.model.run(batch.view())?;
            if self.config.flip {
                let mirror = net.model.run(flip::mirrored(&batch).view())?;
                flip::average_with_mirror(&mut out, &mirror);
            }
            match outputs.as_mut() {
                None => outputs = Some(out),
                Some(o) => o.append(out),
            }
        }
        let outputs = outputs.expect("a canvas has at least one tile");
        timings.inference += ms(t1);

        let t2 = Instant::now();
        let (cw, ch) = canvas.image.dimensions();
        let raw = stitch(&outputs, &canvas.tiles, cw, ch, c.outputs.stride);
        let p = net.postprocess;
        let mut pan = panoptic(&raw, c, p);
        keep_attached(&mut pan, &canvas.image, c, p.attach_radius, p.min_leaf_area);
        split_pieces(&mut pan, p.split_min_area, p.split_gap, p.split_max_leaf_share);
        if let Some(plant) = canvas.plant {
            keep_centred_in_plant(&mut pan, plant, c.outputs.stride);
        }
        timings.postprocess += ms(t2);
        Ok((canvas, pan))
    }
}

/// Whether output pixel `(x, y)` lies in the plant's box (canvas pixels
/// `[x0, y0, x1, y1]`, with `PLANT_MARGIN` of slack).
fn in_plant(plant: [i64; 4], stride: u32, x: f64, y: f64) -> bool {
    let [x0, y0, x1, y1] = plant;
    let (x, y, m) = (x * f64::from(stride), y * f64::from(stride), PLANT_MARGIN);
    x >= (x0 - m) as f64 && x < (x1 + m) as f64 && y >= (y0 - m) as f64 && y < (y1 + m) as f64
}

/// The chamber's frames and panels sometimes look leaf-like to the model:
/// an instance, or a tip, centred outside the plant's box is not a leaf.
fn keep_centred_in_plant(pan: &mut Panoptic, plant: [i64; 4], stride: u32) {
    pan.retain(|seg| in_plant(plant, stride, f64::from(seg.centre[0]), f64::from(seg.centre[1])));
    if let Some(tips) = pan.tips.as_mut() {
        tips.retain(|t| in_plant(plant, stride, f64::from(t.x), f64::from(t.y)));
    }
}

/// The decoder's offsets also join specks on the chamber's frames to a leaf
/// far away: the pixels of kept instances outside the plant's box are not
/// leaf, whichever leaf they were joined to.
fn clear_outside_plant(pan: &mut Panoptic, plant: [i64; 4], stride: u32) {
    let w = pan.width;
    let mut cleared = false;
    for (k, id) in pan.instance.iter_mut().enumerate() {
        if *id != 0 && !in_plant(plant, stride, (k % w) as f64 + 0.5, (k / w) as f64 + 0.5) {
            *id = 0;
            cleared = true;
        }
    }
    if cleared {
        pan.refresh_extents();
        pan.retain(|seg| seg.area > 0);
    }
}

/// Converts a canvas panoptic result into original-image instances, counting
/// leaves by `params`' count rule.
pub fn to_result(
    c: &Contract,
    pan: &Panoptic,
    canvas: &Canvas,
    size: (u32, u32),
    params: &PostprocessParams,
) -> CountResult {
    let s = c.outputs.stride as f32;
    let px_area = (s / canvas.scale).powi(2);
    let clamp = |v: f32, max: u32| (v.round().max(0.0) as u32).min(max);
    let instances: Vec<Instance> = pan
        .segments
        .iter()
        .map(|seg| {
            let [x0, y0] = canvas.to_original(seg.bbox[0] as f32 * s, seg.bbox[1] as f32 * s);
            let [x1, y1] = canvas.to_original(seg.bbox[2] as f32 * s, seg.bbox[3] as f32 * s);
            let [cx, cy] = canvas.to_original((seg.centre[0] + 0.5) * s, (seg.centre[1] + 0.5) * s);
            Instance {
                id: seg.id,
                class: seg.class,
                class_name: c.classes.names[seg.class as usize].clone(),
                area: (seg.area as f32 * px_area).round() as u64,
                bbox: [
                    clamp(x0, size.0),
                    clamp(y0, size.1),
                    clamp(x1, size.0),
                    clamp(y1, size.1),
                ],
                centre: [cx, cy],
                score: seg.score,
            }
        })
        .collect();
    let tips = pan
        .tips
        .iter()
        .flatten()
        .map(|t| {
            let [x, y] = canvas.to_original((t.x as f32 + 0.5) * s, (t.y as f32 + 0.5) * s);
            [x, y, t.score]
        })
        .collect();
    let tip_instances = pan.tip_segments(params.tip_reach);
    CountResult {
        leaf_count: pan.leaf_count_of(params.count_rule, &tip_instances) as u32,
        instances,
        image_size: [size.0, size.1],
        region: canvas.region,
        scale: canvas.scale,
        tiles: canvas.tiles.len() as u32,
        ms: StageTimings::default(),
        tip_instances,
        tips,
        camera: None,
    }
}

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::panoptic::{Segment, TipPeak};
    use crate::tips::CountRule;
    use image::RgbImage;
    use phyllo_contract::LEAF;

    /// Issue 44: a leaf's specks on the chamber's frame, far outside the
    /// plant's box, are dropped from it; the leaf and its count stay.
    #[test]
    fn specks_outside_the_plant_leave_the_leaf_they_were_joined_to() {
        let (w, h) = (64usize, 32usize);
        let mut instance = vec![0u32; w * h];
        // Leaf 1: a blade in columns 10..20, rows 10..14, and a speck at (60, 1).
        for y in 10..14 {
            for x in 10..20 {
                instance[y * w + x] = 1;
            }
        }
        instance[w + 60] = 1;
        let mut pan = Panoptic {
            height: h,
            width: w,
            semantic: instance.iter().map(|&i| if i > 0 { LEAF } else { 0 }).collect(),
            instance,
            segments: vec![Segment {
                id: 1,
                class: LEAF,
                area: 41,
                bbox: [10, 1, 61, 14],
                centre: [15.0, 12.0],
                score: 1.0,
            }],
            tips: None,
        };
        // The plant's box in canvas pixels (stride 2): output columns 8..24.
        clear_outside_plant(&mut pan, [16, 16, 48, 32], 2);
        assert_eq!(pan.segments.len(), 1);
        assert_eq!(pan.segments[0].area, 40);
        assert_eq!(pan.segments[0].bbox, [10, 10, 20, 14]);
        assert_eq!(pan.instance[w + 60], 0);
    }

    #[test]
    fn each_tip_names_the_leaf_it_joins_in_the_result() {
        let (w, h) = (8usize, 4usize);
        // Leaf 1 fills columns 0..4, leaf 2 columns 4..8 of row 0; rows 1.. are background.
        let mut instance = vec![0u32; w * h];
        let mut semantic = vec![0u8; w * h];
        for x in 0..w {
            instance[x] = if x < 4 { 1 } else { 2 };
            semantic[x] = LEAF;
        }
        let seg = |id| Segment {
            id,
            class: LEAF,
            area: 4,
            bbox: [0, 0, 4, 1],
            centre: [0.0, 0.0],
            score: 1.0,
        };
        let tip = |x, y| TipPeak { x, y, score: 0.9 };
        let pan = Panoptic {
            height: h,
            width: w,
            semantic,
            instance,
            segments: vec![seg(1), seg(2)],
            tips: Some(vec![tip(0, 0), tip(3, 0), tip(7, 3)]),
        };
        let canvas = Canvas {
            image: RgbImage::new(16, 8),
            scale: 1.0,
            origin: [0, 0],
            region: [0, 0, 16, 8],
            plant: None,
            tiles: vec![[0, 0]],
        };
        let params = PostprocessParams {
            count_rule: CountRule::Split,
            tip_reach: 0,
            ..PostprocessParams::default()
        };
        let r = to_result(Contract::embedded(), &pan, &canvas, (16, 8), &params);
        assert_eq!(r.tip_instances, vec![Some(1), Some(1), None]);
        assert_eq!(r.tips.len(), 3);
        // Leaf 1 holds two tips, leaf 2 none: split counts 2 + 1.
        assert_eq!(r.leaf_count, 3);
        let json = serde_json::to_value(&r).unwrap();
        assert_eq!(json["tip_instances"], serde_json::json!([1, 1, null]));
    }
}
