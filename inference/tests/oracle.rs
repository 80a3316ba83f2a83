//! Oracle round trip: from a known panoptic label, build the outputs a perfect
//! model would produce, run them through tiling, stitching and
//! post-processing, and recover exactly the same instances.

use std::collections::{BTreeMap, BTreeSet};

use ndarray::{Array2, Array3};
use phyllo_contract::{Contract, LEAF, STEM};
use phyllo_inference::postprocess::{panoptic, PostprocessParams, RawOutputs};
use phyllo_inference::stitch::{cut_tile, stitch};
use phyllo_inference::tiling::tile_starts;

/// A panoptic label at model input scale: (class, instance) per pixel.
struct Label {
    w: usize,
    h: usize,
    class: Vec<u8>,
    inst: Vec<u16>,
}

impl Label {
    fn new(w: usize, h: usize) -> Self {
        Self {
            w,
            h,
            class: vec![0; w * h],
            inst: vec![0; w * h],
        }
    }

    /// Paints a capsule (thick segment) from a to b.
    fn capsule(&mut self, a: (f32, f32), b: (f32, f32), radius: f32, class: u8, inst: u16) {
        for y in 0..self.h {
            for x in 0..self.w {
                let p = (x as f32 + 0.5, y as f32 + 0.5);
                let (dx, dy) = (b.0 - a.0, b.1 - a.1);
                let t = (((p.0 - a.0) * dx + (p.1 - a.1) * dy) / (dx * dx + dy * dy)).clamp(0.0, 1.0);
                let d = ((a.0 + t * dx - p.0).powi(2) + (a.1 + t * dy - p.1).powi(2)).sqrt();
                if d <= radius {
                    self.class[y * self.w + x] = class;
                    self.inst[y * self.w + x] = inst;
                }
            }
        }
    }

    /// The label sampled at output resolution (top-left pixel of each block).
    fn at_stride(&self, s: usize) -> (usize, usize, Vec<u8>, Vec<u16>) {
        let (w, h) = (self.w / s, self.h / s);
        let mut class = vec![0; w * h];
        let mut inst = vec![0; w * h];
        for y in 0..h {
            for x in 0..w {
                class[y * w + x] = self.class[y * s * self.w + x * s];
                inst[y * w + x] = self.inst[y * s * self.w + x * s];
            }
        }
        (w, h, class, inst)
    }
}

/// What a perfect Panoptic-DeepLab model outputs for `label`.
fn perfect_outputs(c: &Contract, label: &Label) -> (RawOutputs, usize, usize, Vec<u8>, Vec<u16>) {
    let s = c.outputs.stride as usize;
    let (w, h, class, inst) = label.at_stride(s);
    let mut sums: BTreeMap<u16, (f64, f64, f64)> = BTreeMap::new();
    for y in 0..h {
        for x in 0..w {
            let i = inst[y * w + x];
            if i > 0 && c.is_thing(class[y * w + x]) {
                let e = sums.entry(i).or_default();
                e.0 += y as f64;
                e.1 += x as f64;
                e.2 += 1.0;
            }
        }
    }
    let centres: BTreeMap<u16, (f32, f32)> = sums
        .iter()
        .map(|(&k, &(sy, sx, n))| (k, ((sy / n) as f32, (sx / n) as f32)))
        .collect();
    let mut semantic = Array3::from_elem((4, h, w), -5.0f32);
    let mut center = Array2::zeros((h, w));
    let mut offset = Array3::zeros((2, h, w));
    let sigma = c.outputs.center_sigma;
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            semantic[[class[i] as usize, y, x]] = 5.0;
            let mut heat = 0f32;
            for &(cy, cx) in centres.values() {
                let d2 = (y as f32 - cy).powi(2) + (x as f32 - cx).powi(2);
                heat = heat.max((-d2 / (2.0 * sigma * sigma)).exp());
            }
            center[[y, x]] = heat;
            if let Some(&(cy, cx)) = centres.get(&inst[i]) {
                offset[[0, y, x]] = cy - y as f32;
                offset[[1, y, x]] = cx - x as f32;
            }
        }
    }
    (
        RawOutputs {
            semantic,
            center,
            offset,
            tip: None,
        },
        w,
        h,
        class,
        inst,
    )
}

/// Runs the perfect outputs through tiling + stitching + post-processing and
/// checks that every truth instance comes back with exactly its pixels.
fn round_trip(label: &Label) -> usize {
    let c = Contract::embedded();
    let s = c.outputs.stride;
    let (full, w, h, class, inst) = perfect_outputs(c, label);
    let t = c.output_tile() as usize;
    let xs = tile_starts(label.w as u32, c.input.tile, c.input.tile_overlap, s);
    let ys = tile_starts(label.h as u32, c.input.tile, c.input.tile_overlap, s);
    let tiles: Vec<[u32; 2]> = ys.iter().flat_map(|&y| xs.iter().map(move |&x| [x, y])).collect();
    let mut outs = cut_tile(&full, tiles[0][0], tiles[0][1], s, t);
    for &[tx, ty] in &tiles[1..] {
        outs.append(cut_tile(&full, tx, ty, s, t));
    }
    let stitched = stitch(&outs, &tiles, label.w as u32, label.h as u32, s);
    let params = PostprocessParams {
        min_leaf_area: 1,
        ..PostprocessParams::default()
    };
    let pan = panoptic(&stitched, c, &params);
    assert_eq!((pan.width, pan.height), (w, h));

    // Truth and predicted pixel sets per instance must match one to one.
    let mut truth: BTreeMap<u16, BTreeSet<usize>> = BTreeMap::new();
    let mut pred: BTreeMap<u32, BTreeSet<usize>> = BTreeMap::new();
    for i in 0..w * h {
        if inst[i] > 0 && c.is_thing(class[i]) {
            truth.entry(inst[i]).or_default().insert(i);
        }
        if pan.instance[i] > 0 {
            pred.entry(pan.instance[i]).or_default().insert(i);
        }
        assert_eq!(pan.semantic[i], class[i], "semantic at pixel {i}");
    }
    let truth_sets: BTreeSet<&BTreeSet<usize>> = truth.values().collect();
    let pred_sets: BTreeSet<&BTreeSet<usize>> = pred.values().collect();
    assert_eq!(truth_sets, pred_sets, "instances differ");
    assert_eq!(pan.count(LEAF), truth.len());
    tiles.len()
}

#[test]
fn leaves_single_tile() {
    let mut l = Label::new(512, 512);
    l.capsule((256.0, 500.0), (256.0, 60.0), 5.0, STEM, 0);
    l.capsule((256.0, 400.0), (80.0, 300.0), 7.0, LEAF, 1);
    l.capsule((256.0, 300.0), (440.0, 220.0), 7.0, LEAF, 2);
    l.capsule((256.0, 200.0), (120.0, 90.0), 6.0, LEAF, 3);
    assert_eq!(round_trip(&l), 1);
}

#[test]
fn leaf_split_by_an_occluding_leaf_stays_one_instance() {
    let mut l = Label::new(512, 512);
    // Leaf 1 runs left to right; leaf 2 crosses in front and cuts it in two.
    l.capsule((60.0, 250.0), (450.0, 250.0), 8.0, LEAF, 1);
    l.capsule((250.0, 60.0), (250.0, 460.0), 14.0, LEAF, 2);
    let (w, h, _, inst) = l.at_stride(2);
    // Check that leaf 1 really is in two disconnected pieces.
    let row = 125 * w;
    let cols: Vec<usize> = (0..w).filter(|&x| inst[row + x] == 1).collect();
    assert!(cols.windows(2).any(|p| p[1] - p[0] > 1), "leaf 1 should be split");
    assert_eq!(h, 256);
    round_trip(&l);
}

#[test]
fn leaves_crossing_tile_borders_are_stitched_into_one() {
    // 1300 x 700: four tiles across, two down.
    let mut l = Label::new(1300, 700);
    l.capsule((650.0, 690.0), (650.0, 40.0), 6.0, STEM, 0);
    l.capsule((650.0, 600.0), (30.0, 450.0), 9.0, LEAF, 1); // crosses the first vertical border
    l.capsule((650.0, 500.0), (1270.0, 380.0), 9.0, LEAF, 2); // crosses the second
    l.capsule((650.0, 350.0), (200.0, 100.0), 8.0, LEAF, 3); // crosses the horizontal border
    l.capsule((650.0, 250.0), (1100.0, 30.0), 8.0, LEAF, 4);
    l.capsule((640.0, 120.0), (520.0, 20.0), 6.0, LEAF, 5);
    // A long leaf cut by leaf 1, crossing a border too.
    l.capsule((100.0, 650.0), (900.0, 560.0), 7.0, LEAF, 6);
    let tiles = round_trip(&l);
    assert_eq!(tiles, 8);
}

#[test]
fn empty_image_has_no_instances() {
    let l = Label::new(512, 512);
    assert_eq!(round_trip(&l), 1);
}
