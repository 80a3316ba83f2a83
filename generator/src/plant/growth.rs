//! Plant development over time: when each leaf appears, how it lengthens and
//! unfurls, when its internode elongates, and when it yellows and dies.
//!
//! A plant's traits are drawn once from its preset ([`PlantTraits::sample`]);
//! [`PlantTraits::at`] then gives its state on any day, so the same plant can
//! be rendered growing across a sequence of imaging days.

use super::preset::{LeafShape, Preset};
use crate::rng::{self, Draw};
use std::f32::consts::PI;

/// Traits of one leaf, fixed for the plant's life.
#[derive(Debug, Clone)]
pub struct LeafTraits {
    /// Day after sowing the tip appears from the whorl.
    pub emergence_day: f32,
    /// Days from tip appearance to full expansion.
    pub expansion_days: f32,
    /// Day the leaf is dead (after yellowing and drying).
    pub death_day: f32,
    /// Days of visible senescence before death.
    pub senescence_days: f32,
    /// Final blade length.
    pub length: f32,
    /// Final maximum blade width.
    pub width: f32,
    /// Relative position of the widest point.
    pub width_peak: f32,
    /// Width at the collar relative to the maximum.
    pub base_width: f32,
    /// Blade angle from vertical at the collar when mature (radians).
    pub insertion: f32,
    /// Droop gain.
    pub droop: f32,
    /// V half-angle across the midrib (radians).
    pub v_angle: f32,
    /// Margin wave amplitude relative to half-width.
    pub waviness: f32,
    /// Margin wave length.
    pub wave_length: f32,
    /// Phase of the margin waves.
    pub wave_phase: f32,
    /// Total twist collar to tip (radians).
    pub twist: f32,
    /// Azimuth of the blade around the stem (radians).
    pub azimuth: f32,
    /// Lateral offsets of the skeleton's control points, relative to length.
    pub wander: [f32; 7],
    /// Relative position along the blade where it buckles.
    pub kink_position: f32,
    /// Extra bend at the buckle when mature (radians; 0 for an even arc).
    pub kink_angle: f32,
    /// Final sheath length.
    pub sheath_length: f32,
    /// Final internode length above this leaf's node.
    pub internode_length: f32,
    /// Days the internode takes to elongate.
    pub elongation_days: f32,
}

/// Traits of a whole plant.
#[derive(Debug, Clone)]
pub struct PlantTraits {
    /// Preset name.
    pub preset: String,
    /// All leaves the plant will ever make, bottom to top.
    pub leaves: Vec<LeafTraits>,
    /// Stem radius at the base of a grown plant.
    pub stem_radius: f32,
    /// Colour multipliers for this plant (genotype x environment).
    pub tint: [f32; 3],
    /// Panicle appearance day, length and radius, if the preset has one.
    pub panicle: Option<(f32, f32, f32)>,
    /// How much wider a sheath is at its collar than at its node (1: a
    /// plain tube). Real sheaths loosen toward the collar, so the stem looks
    /// knobbly where leaves leave it.
    pub sheath_flare: f32,
    /// Whether the sheaths have the blades' green instead of the stem's
    /// colour, as on most real maize and sorghum: the model must learn that a
    /// green tube hugging the stem is stem, not a leaf of its own.
    pub green_sheaths: bool,
    /// Whether dead leaves leave a dried sheath and a blade stub (stem) behind
    /// instead of vanishing; see the preset's `dead_remnant_chance`.
    pub dead_remnants: bool,
}

/// State of one leaf on one day.
#[derive(Debug, Clone)]
pub struct LeafState {
    /// Rank of the leaf on the plant (0 = first leaf).
    pub rank: usize,
    /// Expansion progress 0..1.
    pub progress: f32,
    /// Current blade length.
    pub length: f32,
    /// 1 = rolled in the whorl, 0 = open.
    pub furl: f32,
    /// 0 = green, 1 = dry just before death.
    pub senescence: f32,
    /// Height of the blade base (collar, or whorl top while furled).
    pub base_height: f32,
    /// Height of this leaf's node.
    pub node_height: f32,
    /// Current sheath length (0 while furled).
    pub sheath_length: f32,
    /// Current blade angle from vertical at the base (radians).
    pub insertion: f32,
    /// Current droop gain.
    pub droop: f32,
    /// Current extra bend at the buckle (radians; 0 for an even arc); where
    /// it sits is the leaf's trait `kink_position`.
    pub kink: f32,
    /// Current width scale (furled leaves are narrower).
    pub width_scale: f32,
}

/// The plant on one day.
#[derive(Debug, Clone)]
pub struct PlantState {
    /// Days after sowing.
    pub age_days: f32,
    /// Living leaves (emerged and not dead), bottom to top.
    pub leaves: Vec<LeafState>,
    /// What is left of dead leaves when the plant keeps remnants
    /// ([`PlantTraits::dead_remnants`]): each a dried sheath and a short,
    /// hanging blade stub, meshed as stem. Empty otherwise.
    pub remnants: Vec<LeafState>,
    /// Leaves whose tip has appeared so far (living or dead).
    pub emerged: usize,
    /// Height of the stem top (whorl).
    pub stem_height: f32,
    /// Current stem radius at the base.
    pub stem_radius: f32,
    /// Panicle length and radius if it has appeared (scaled by its growth).
    pub panicle: Option<(f32, f32)>,
}

/// Bell-shaped length profile over `rank` (0 first leaf, 1 flag leaf),
/// relative to the longest leaf: short first leaves, the longest around
/// `longest`, a shorter flag leaf.
fn length_profile(rank: f32, longest: f32, first_frac: f32, last_frac: f32) -> f32 {
    if rank <= longest {
        first_frac + (1.0 - first_frac) * (0.5 - 0.5 * (PI * rank / longest.max(1e-3)).cos())
    } else {
        let x = (rank - longest) / (1.0 - longest).max(1e-3);
        1.0 - (1.0 - last_frac) * x * x
    }
}

/// Lateral offsets of a leaf skeleton's control points, growing toward the
/// tip; the first stays on the collar.
fn draw_wander(r: &mut impl Draw, amp: f32) -> [f32; 7] {
    let mut wander = [0.0f32; 7];
    for (k, w) in wander.iter_mut().enumerate() {
        *w = if k == 0 {
            0.0
        } else {
            r.normal(0.0, amp) * (k as f32 / 6.0)
        };
    }
    wander
}

/// Where leaf `i` buckles and by how much (0 for an even arc); the preset's
/// chance is scaled by `rel_length`, the leaf's length over the longest's.
/// Drawn from a stream of its own, so adding buckles left every other trait
/// of an existing seed as it was.
fn draw_kink(l: &LeafShape, seed: u64, i: usize, rel_length: f32) -> (f32, f32) {
    let mut k = rng::stream(seed, "leaf-kink", i as u64);
    let buckles = k.chance(l.kink_chance * rel_length.min(1.0));
    let kink_position = k.range(l.kink_position);
    let kink_angle = if buckles {
        k.range(l.kink_angle_deg).to_radians()
    } else {
        0.0
    };
    (kink_position, kink_angle)
}

fn smoothstep(x: f32) -> f32 {
    let x = x.clamp(0.0, 1.0);
    x * x * (3.0 - 2.0 * x)
}

impl PlantTraits {
    /// Draws a plant's traits from a preset.
    pub fn sample(preset: &Preset, seed: u64) -> Self {
        let mut r = rng::stream(seed, "plant-traits", 0);
        let g = &preset.growth;
        let l = &preset.leaf;
        let s = &preset.stem;
        let [nlo, nhi] = g.final_leaf_count;
        let n = (r.uniform(nlo as f32, nhi as f32 + 0.999) as u32).clamp(nlo, nhi) as usize;
        let phyllo = r.range(g.phyllochron_days);
        let expansion = r.range(g.expansion_days);
        let max_len = r.range(l.max_length);
        let longest = r.range(l.longest_rank);
        let first_frac = r.range(l.first_length_fraction);
        let last_frac = r.range(l.last_length_fraction);
        let width_ratio = r.range(l.width_ratio);
        let insertion = r.range(l.insertion_angle_deg);
        let per_rank = r.range(l.insertion_angle_per_rank_deg);
        let droop = r.range(l.droop);
        let internode = r.range(s.internode_length);
        let sheath_frac = r.range(s.sheath_fraction);
        let lifespan = r.range(g.lifespan_days);
        let azimuth0 = r.uniform(0.0, 2.0 * PI);
        let mut day = r.range(g.first_emergence_day);
        let mut leaves = Vec::with_capacity(n);
        for i in 0..n {
            let rank = if n > 1 { i as f32 / (n - 1) as f32 } else { 0.5 };
            let rel = length_profile(rank, longest, first_frac, last_frac);
            let length = max_len * rel * r.normal(1.0, 0.05).clamp(0.85, 1.15);
            let width = length
                * width_ratio
                * r.normal(1.0, 0.06).clamp(0.8, 1.2)
                * (0.75 + 0.25 * rank.min(0.6) / 0.6);
            let exp_days = expansion * r.normal(1.0, 0.08).clamp(0.8, 1.2);
            let life = lifespan * r.normal(1.0, 0.1).clamp(0.75, 1.25) * (1.0 + 0.6 * rank);
            let sen = r.range(g.senescence_days);
            let wander_amp = r.range(l.wander);
            let wander = draw_wander(&mut r, wander_amp);
            let internode_length = if (i as u32) < s.elongation_start_rank {
                0.004 + 0.004 * r.random_unit()
            } else {
                internode * r.normal(1.0, 0.12).clamp(0.6, 1.4)
            };
            let (kink_position, kink_angle) = draw_kink(l, seed, i, length / max_len);
            leaves.push(LeafTraits {
                emergence_day: day,
                expansion_days: exp_days,
                death_day: day + exp_days + life,
                senescence_days: sen,
                length,
                width,
                width_peak: r.range(l.width_peak),
                base_width: r.range(l.base_width),
                insertion: (insertion + r.normal(0.0, 4.0)).to_radians().clamp(0.05, 1.4),
                droop: droop * r.normal(1.0, 0.12).clamp(0.6, 1.4),
                v_angle: r.range(l.v_angle_deg).to_radians(),
                waviness: r.range(l.waviness),
                wave_length: r.range(l.wave_length),
                wave_phase: r.uniform(0.0, 2.0 * PI),
                twist: r.range(l.twist_deg).to_radians(),
                azimuth: azimuth0 + i as f32 * PI + r.normal(0.0, l.azimuth_sd_deg.to_radians()),
                wander,
                kink_position,
                kink_angle,
                sheath_length: length * sheath_frac * r.normal(1.0, 0.08).clamp(0.8, 1.2),
                internode_length,
                elongation_days: r.range(s.elongation_days),
            });
            day += phyllo * r.normal(1.0, 0.1).clamp(0.7, 1.3);
        }
        let tint_j = preset.colour.jitter;
        let tint = [
            r.normal(1.0, tint_j),
            r.normal(1.0, tint_j),
            r.normal(1.0, tint_j),
        ]
        .map(|x| x.clamp(0.6, 1.5));
        let panicle = preset
            .panicle
            .as_ref()
            .map(|p| (r.range(p.emergence_day), r.range(p.length), r.range(p.radius)));
        let stem_radius = r.range(s.base_radius);
        // Drawn last so that every earlier trait of a seed stays as it was.
        let sheath_flare = r.uniform(1.0, 1.7);
        let green_sheaths = r.chance(0.6);
        let mut traits = PlantTraits {
            preset: preset.name.clone(),
            leaves,
            stem_radius,
            tint,
            panicle,
            sheath_flare,
            green_sheaths,
            // A stream of its own: with the chance at 0 every plant is drawn as before.
            dead_remnants: rng::stream(seed, "dead-remnants", 0).chance(g.dead_remnant_chance),
        };
        traits.apply_rank_angle(per_rank.to_radians());
        traits
    }

    /// Lower leaves sit at wider angles: leaf `i` of `n` gets `per_rank`
    /// radians more than the one above it, up to a limit.
    fn apply_rank_angle(&mut self, per_rank: f32) {
        let n = self.leaves.len();
        for (i, leaf) in self.leaves.iter_mut().enumerate() {
            let below_top = (n - 1 - i) as f32;
            leaf.insertion = (leaf.insertion + per_rank * below_top.min(8.0)).min(1.45);
        }
    }

    /// Number of leaves living on `age_days` (emerged and not yet dead).
    pub fn living_on(&self, age_days: f32) -> usize {
        self.leaves
            .iter()
            .filter(|l| age_days >= l.emergence_day && age_days < l.death_day)
            .count()
    }

    /// Number of leaves emerged by `age_days`, dead ones included.
    pub fn emerged_by(&self, age_days: f32) -> usize {
        self.leaves.iter().filter(|l| age_days >= l.emergence_day).count()
    }

    /// The plant's state on `age_days`.
    pub fn at(&self, age_days: f32) -> PlantState {
        let t = age_days;
        let growth = smoothstep(t / 45.0);
        let stem_radius = self.stem_radius * (0.35 + 0.65 * growth);
        // Node heights from elongated internodes.
        let mut nodes = Vec::with_capacity(self.leaves.len());
        let mut h = 0.0f32;
        for leaf in &self.leaves {
            nodes.push(h);
            let start = leaf.emergence_day + leaf.expansion_days;
            h += leaf.internode_length * smoothstep((t - start) / leaf.elongation_days);
        }
        // Collars of leaves whose collar has emerged (progress >= 0.6) stack
        // up the pseudostem; younger leaves come out of the top of it.
        let mut whorl_top = 0.01f32;
        let mut collar = vec![0.0f32; self.leaves.len()];
        let mut progress = vec![0.0f32; self.leaves.len()];
        for (i, leaf) in self.leaves.iter().enumerate() {
            if t < leaf.emergence_day {
                break;
            }
            let p = ((t - leaf.emergence_day) / leaf.expansion_days).clamp(0.0, 1.0);
            progress[i] = p;
            let sheath = leaf.sheath_length * smoothstep((p - 0.35) / 0.65);
            let c = (nodes[i] + sheath).max(whorl_top + 0.004);
            collar[i] = c;
            if p >= 0.6 {
                whorl_top = whorl_top.max(c);
            }
        }
        let mut leaves = Vec::new();
        let mut remnants = Vec::new();
        let mut emerged = 0;
        for (i, leaf) in self.leaves.iter().enumerate() {
            if t < leaf.emergence_day {
                break;
            }
            emerged += 1;
            if t >= leaf.death_day {
                if self.dead_remnants {
                    remnants.push(remnant(i, leaf, nodes[i], collar[i]));
                }
                continue;
            }
            let p = progress[i];
            let open = smoothstep((p - 0.45) / 0.45);
            let sen_start = leaf.death_day - leaf.senescence_days;
            let senescence = ((t - sen_start) / leaf.senescence_days).clamp(0.0, 1.0);
            let furled = open < 1.0 && p < 0.6;
            leaves.push(LeafState {
                rank: i,
                progress: p,
                length: leaf.length * (0.08 + 0.92 * smoothstep(p * 1.1)),
                furl: 1.0 - open,
                senescence,
                base_height: if furled { whorl_top } else { collar[i] },
                node_height: nodes[i],
                sheath_length: if furled { 0.0 } else { collar[i] - nodes[i] },
                insertion: 0.04 + (leaf.insertion - 0.04) * open,
                droop: leaf.droop * open * (1.0 + 0.8 * senescence),
                kink: leaf.kink_angle * open,
                width_scale: 0.45 + 0.55 * open,
            });
        }
        let stem_height = whorl_top.max(leaves.iter().map(|l| l.base_height).fold(0.0, f32::max));
        let panicle = self.panicle.and_then(|(day, len, rad)| {
            (t >= day).then(|| {
                let g = smoothstep((t - day) / 8.0).max(0.1);
                (len * g, rad * g)
            })
        });
        PlantState {
            age_days,
            leaves,
            remnants,
            emerged,
            stem_height,
            stem_radius,
            panicle,
        }
    }
}

/// The remnant of dead leaf `rank`: its sheath stays from node to collar and
/// the blade has broken off a short way out, the stub shrivelled (narrow) and
/// hanging. Its size and dryness vary from leaf to leaf with the leaf's wave
/// phase, a uniform trait, so that no random draw is added.
fn remnant(rank: usize, leaf: &LeafTraits, node: f32, collar: f32) -> LeafState {
    let v = leaf.wave_phase / (2.0 * PI);
    LeafState {
        rank,
        progress: 1.0,
        length: leaf.length * (0.06 + 0.14 * v),
        furl: 0.0,
        senescence: 0.55 + 0.3 * (1.0 - v),
        base_height: collar,
        node_height: node,
        sheath_length: collar - node,
        insertion: (leaf.insertion + 0.3).min(1.45),
        droop: 1.6,
        kink: 0.0,
        width_scale: 0.35 + 0.2 * v,
    }
}

/// A uniform draw in `[0, 1)` (helper so traits code reads plainly).
trait UnitDraw {
    fn random_unit(&mut self) -> f32;
}

impl<R: rand::Rng> UnitDraw for R {
    fn random_unit(&mut self) -> f32 {
        self.random::<f32>()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn leaves_emerge_and_die_in_order() {
        let preset = Preset::load("btx623").unwrap();
        let traits = PlantTraits::sample(&preset, 42);
        let mut last_emerged = 0;
        for day in 5..70 {
            let s = traits.at(day as f32);
            assert!(s.emerged >= last_emerged, "emerged count never drops");
            last_emerged = s.emerged;
            assert_eq!(s.leaves.len(), traits.living_on(day as f32));
        }
        let young = traits.at(20.0);
        let old = traits.at(56.0);
        assert!(old.stem_height > young.stem_height);
        assert!(old.emerged > young.emerged);
    }

    #[test]
    fn buckles_come_from_their_own_stream_and_leave_other_traits_alone() {
        let mut never = Preset::load("maize").unwrap();
        never.leaf.kink_chance = 0.0;
        let mut always = never.clone();
        always.leaf.kink_chance = 1.0;
        let (a, b) = (PlantTraits::sample(&never, 7), PlantTraits::sample(&always, 7));
        assert!(a.leaves.iter().all(|l| l.kink_angle == 0.0));
        // The longest leaf buckles for sure at chance 1, shorter ones in
        // proportion to their length.
        assert!(b.leaves.iter().filter(|l| l.kink_angle > 0.0).count() >= 1);
        for (x, y) in a.leaves.iter().zip(&b.leaves) {
            assert_eq!(
                (x.length, x.insertion, x.droop, x.azimuth),
                (y.length, y.insertion, y.droop, y.azimuth)
            );
            assert_eq!(x.kink_position, y.kink_position);
        }
        // A buckle opens with the leaf: none while it is still furled.
        let young = b.at(b.leaves[3].emergence_day + 0.1);
        assert!(young.leaves.iter().filter(|l| l.rank == 3).all(|l| l.kink == 0.0));
    }

    /// Mean number of leaves not yet fully open, and the mean collar height
    /// of the top open leaf relative to the whole plant's, over 24 plants
    /// at 25-46 days.
    fn top_of_plant(preset: &str) -> (f32, f32) {
        let preset = Preset::load(preset).unwrap();
        let (mut opening, mut collar_share, mut n) = (0.0, 0.0, 0.0);
        for seed in 0..24 {
            let traits = PlantTraits::sample(&preset, seed);
            for day in [25.0, 32.0, 39.0, 46.0] {
                let s = traits.at(day);
                opening += s.leaves.iter().filter(|l| l.furl > 0.0).count() as f32;
                let open_top = s
                    .leaves
                    .iter()
                    .filter(|l| l.furl == 0.0)
                    .map(|l| l.base_height)
                    .fold(0.0, f32::max);
                let top = s
                    .leaves
                    .iter()
                    .map(|l| l.base_height + l.length)
                    .fold(0.0, f32::max);
                collar_share += open_top / top;
                n += 1.0;
            }
        }
        (opening / n, collar_share / n)
    }

    #[test]
    fn the_whorl_preset_has_several_leaves_opening_low_on_a_compact_stem() {
        let (maize_opening, maize_collars) = top_of_plant("maize");
        let (whorl_opening, whorl_collars) = top_of_plant("maize-whorl");
        // Printed for models/EXPERIMENTS.md ("Crowded maize tops"; `-- --nocapture`).
        eprintln!(
            "leaves opening: maize {maize_opening:.2}, maize-whorl {whorl_opening:.2}; \
             top open collar at {maize_collars:.2} vs {whorl_collars:.2} of the plant's height"
        );
        // Real young maize shows two to four leaves rising out of the whorl.
        assert!(
            (2.0..=4.0).contains(&whorl_opening),
            "{whorl_opening} leaves opening"
        );
        assert!(
            whorl_opening > maize_opening + 0.8,
            "{whorl_opening} vs maize {maize_opening}"
        );
        assert!(
            whorl_collars < maize_collars,
            "collars at {whorl_collars} of the height vs maize {maize_collars}"
        );
    }
}
