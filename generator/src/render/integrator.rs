//! The path tracer: next-event estimation to the chamber's area lights at
//! every plant vertex, one or more diffuse bounces with Russian roulette.
//! Rays that miss the plant take the chamber's analytic radiance.

use super::{materials::Rgb, Scene};
use crate::rng::PixelRng;
use glam::Vec3;

/// Offset that lifts secondary rays off the surface they leave.
const EPS: f32 = 2e-5;
/// Light samples at the first surface a camera ray hits.
const NEE_PRIMARY: u32 = 3;
/// Largest direct radiance one vertex may return.
const FIREFLY: f32 = 0.8;

/// Result of tracing one camera ray.
pub struct Sample {
    /// Radiance.
    pub radiance: Rgb,
    /// Label value of the first surface hit (0 for chamber/background).
    pub label: u16,
    /// Rays cast (camera, bounce and shadow).
    pub rays: u32,
}

/// Traces a camera ray from `origin` along unit `dir`, both in chamber space.
#[inline]
pub fn trace(scene: &Scene, origin: Vec3, dir: Vec3, rng: &mut PixelRng, max_depth: u32) -> Sample {
    let mut radiance = Vec3::ZERO;
    let mut beta = Vec3::ONE;
    let mut o = origin;
    let mut d = dir;
    let mut label = 0u16;
    let mut rays = 0u32;
    for depth in 0..max_depth {
        rays += 1;
        let Some(hit) = scene.hit(o, d) else {
            radiance += beta * Vec3::from(scene.chamber.radiance(o, d, depth == 0));
            break;
        };
        if depth == 0 {
            label = scene.label_of(&hit.info);
        }
        let p = o + d * hit.t;
        let n = hit.normal;
        let wo = -d;
        let bsdf = scene.materials.bsdf(hit.info.material, hit.info.senescence);
        if super::materials::Materials::is_prop(hit.info.material) {
            let front = if n.dot(wo) >= 0.0 { n } else { -n };
            radiance += beta * scene.chamber.prop_radiance(bsdf.reflectance, front);
            break;
        }
        let lift = |w: Vec3| p + n * (EPS * n.dot(w).signum());
        // Next-event estimation: several stratified light samples at the
        // first vertex (the chamber's lights are huge, so visibility through
        // the foliage is the main noise), one deeper down.
        let n_light = if depth == 0 { NEE_PRIMARY } else { 1 };
        let mut direct = Vec3::ZERO;
        for k in 0..n_light {
            let u = (k as f32 + rng.uniform01()) / n_light as f32;
            let (light, p_sel) = scene.chamber.pick_light(u);
            let q = light.point(rng.uniform01(), rng.uniform01());
            let to = q - p;
            let dist2 = to.length_squared();
            let dist = dist2.sqrt();
            let wi = to / dist;
            let cos_l = -light.normal().dot(wi);
            if cos_l <= 0.0 {
                continue;
            }
            let f = bsdf.eval(n, wo, wi);
            if f.max_element() <= 0.0 {
                continue;
            }
            rays += 1;
            if scene.occluded(lift(wi), wi, dist * 0.999) {
                continue;
            }
            let le = match light.finish {
                super::walls::Finish::Emitter(le) => Vec3::from(le),
                super::walls::Finish::Matte(_) => Vec3::ZERO,
            };
            let g = n.dot(wi).abs() * cos_l / dist2;
            direct += f * le * (g * light.area() / p_sel);
        }
        direct /= n_light as f32;
        // Clamp rare fireflies (grazing gloss times a large light's weight):
        // a small bias that keeps a few samples per pixel presentable.
        let peak = direct.max_element();
        if peak > FIREFLY {
            direct *= FIREFLY / peak;
        }
        radiance += beta * direct;
        if depth + 1 == max_depth {
            break;
        }
        let Some((wi, w)) = bsdf.sample(n, wo, rng.uniform01(), rng.uniform01(), rng.uniform01()) else {
            break;
        };
        beta *= w;
        // Russian roulette once the path has lost most of its weight.
        let keep = beta.max_element().min(0.95);
        if depth >= 1 {
            if rng.uniform01() >= keep {
                break;
            }
            beta /= keep;
        }
        o = lift(wi);
        d = wi;
    }
    Sample {
        radiance,
        label,
        rays,
    }
}
