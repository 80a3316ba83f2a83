//! Surface scattering. Leaves are thin two-sided sheets in the spirit of
//! Baranoski–Rokne: diffuse reflection and diffuse transmission (the light
//! that makes a backlit leaf glow) plus a glossy cuticle with Schlick
//! Fresnel. Senescence moves the colours from green to yellow to brown and
//! removes transmittance as the leaf dries. Other plant parts and the props
//! are diffuse.

use crate::plant::preset::Colour;
use glam::Vec3;
use std::f32::consts::{FRAC_1_PI, PI};

/// Linear RGB triple.
pub type Rgb = Vec3;

/// Scattering at one shading point.
#[derive(Debug, Clone, Copy)]
pub struct Bsdf {
    /// Diffuse reflectance.
    pub reflectance: Rgb,
    /// Diffuse transmittance (0 for opaque surfaces).
    pub transmittance: Rgb,
    /// Weight of the glossy cuticle lobe (0 for none).
    pub gloss: f32,
}

/// Cuticle reflectance at normal incidence (wax, n ≈ 1.5).
const F0: f32 = 0.04;
/// Blinn–Phong exponent of the cuticle sheen.
const GLOSS_EXP: f32 = 24.0;

impl Bsdf {
    /// BSDF value for unit directions `wo` (to the viewer) and `wi` (to the
    /// light) about geometric normal `n`, either side.
    #[inline]
    pub fn eval(&self, n: Vec3, wo: Vec3, wi: Vec3) -> Rgb {
        let co = n.dot(wo);
        let ci = n.dot(wi);
        if co * ci > 0.0 {
            let mut f = self.reflectance * FRAC_1_PI;
            if self.gloss > 0.0 {
                let h = (wo + wi).normalize_or_zero();
                let nh = n.dot(h).abs();
                let fresnel = F0 + (1.0 - F0) * (1.0 - wi.dot(h).max(0.0)).powi(5);
                f += Vec3::splat(self.gloss * fresnel * (GLOSS_EXP + 8.0) / (8.0 * PI) * nh.powf(GLOSS_EXP));
            }
            f
        } else {
            self.transmittance * FRAC_1_PI
        }
    }

    /// Samples a diffuse bounce from uniforms `(u0, u1, u2)`. Returns the new
    /// direction and the throughput weight `f·cos/pdf`.
    #[inline]
    pub fn sample(&self, n: Vec3, wo: Vec3, u0: f32, u1: f32, u2: f32) -> Option<(Vec3, Rgb)> {
        let front = if n.dot(wo) >= 0.0 { n } else { -n };
        let r = lum(self.reflectance);
        let t = lum(self.transmittance);
        if r + t <= 0.0 {
            return None;
        }
        let p_r = r / (r + t);
        let (side, weight) = if u0 < p_r {
            (front, self.reflectance / p_r)
        } else {
            (-front, self.transmittance / (1.0 - p_r))
        };
        Some((cosine_hemisphere(side, u1, u2), weight))
    }
}

/// Luminance-like average used for sampling decisions.
#[inline]
pub fn lum(c: Rgb) -> f32 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

/// Cosine-weighted direction about `n`.
#[inline]
pub fn cosine_hemisphere(n: Vec3, u1: f32, u2: f32) -> Vec3 {
    let r = u1.sqrt();
    let phi = 2.0 * PI * u2;
    let (t, b) = n.any_orthonormal_pair();
    (t * (r * phi.cos()) + b * (r * phi.sin()) + n * (1.0 - u1).max(0.0).sqrt()).normalize()
}

/// The material table of one scene, indexed by `TriInfo::material`.
#[derive(Debug, Clone)]
pub struct Materials {
    leaf_r: Rgb,
    leaf_t: Rgb,
    senescent: Rgb,
    dry: Rgb,
    stem: Rgb,
    panicle: Rgb,
    pot: Rgb,
    soil: Rgb,
    carrier: Rgb,
}

impl Materials {
    /// Materials for a plant's colours (times its tint) and the props.
    pub fn new(c: &Colour, tint: [f32; 3], panicle: [f32; 3], pot: [f32; 3]) -> Self {
        let t = Vec3::from(tint);
        let leaf_r = (Vec3::from(c.leaf_reflectance) * t).min(Vec3::splat(0.9));
        let leaf_t = (Vec3::from(c.leaf_transmittance) * t).min(Vec3::ONE - leaf_r);
        Materials {
            leaf_r,
            leaf_t,
            senescent: Vec3::from(c.senescent_reflectance),
            dry: Vec3::from(c.dry_reflectance),
            stem: Vec3::from(c.stem_reflectance) * t,
            panicle: Vec3::from(panicle),
            pot: Vec3::from(pot),
            soil: Vec3::new(0.05, 0.035, 0.025),
            carrier: Vec3::new(0.02, 0.02, 0.02),
        }
    }

    /// Whether material `id` is a prop shaded by ambient light only.
    #[inline]
    pub fn is_prop(id: u16) -> bool {
        use crate::render::chamber::materials as cm;
        matches!(id, cm::POT | cm::SOIL | cm::CARRIER)
    }

    /// Scattering of material `id` at senescence `s`.
    #[inline]
    pub fn bsdf(&self, id: u16, s: f32) -> Bsdf {
        use crate::plant::materials as pm;
        use crate::render::chamber::materials as cm;
        let diffuse = |c: Rgb| Bsdf {
            reflectance: c,
            transmittance: Vec3::ZERO,
            gloss: 0.0,
        };
        match id {
            pm::LEAF => {
                let (r, t) = if s <= 0.5 {
                    let k = s / 0.5;
                    (
                        self.leaf_r.lerp(self.senescent, k),
                        self.leaf_t.lerp(self.senescent * 0.6, k),
                    )
                } else {
                    let k = (s - 0.5) / 0.5;
                    (
                        self.senescent.lerp(self.dry, k),
                        (self.senescent * 0.6).lerp(self.dry * 0.15, k),
                    )
                };
                Bsdf {
                    reflectance: r,
                    transmittance: t,
                    gloss: 1.0 - 0.8 * s,
                }
            }
            pm::STEM => Bsdf {
                reflectance: self.stem.lerp(self.senescent, s),
                transmittance: self.stem * 0.3,
                gloss: 0.5,
            },
            pm::PANICLE => diffuse(self.panicle),
            cm::POT => diffuse(self.pot),
            cm::SOIL => diffuse(self.soil),
            cm::CARRIER => Bsdf {
                reflectance: self.carrier,
                transmittance: Vec3::ZERO,
                gloss: 0.6,
            },
            _ => diffuse(Vec3::splat(0.5)),
        }
    }
}
