//! Rendering a plant in the chamber: scene set-up per view, the camera
//! window, and the parallel pixel loop that produces the RGB image and the
//! exact panoptic label from the same primary rays.

pub mod accel;
pub mod camera;
pub mod chamber;
pub mod film;
pub mod fittings;
pub mod integrator;
pub mod look;
pub mod materials;
pub mod walls;

use crate::label::LabelImage;
use crate::mesh::{Mesh, TriInfo};
use crate::plant::preset::Preset;
use crate::plant::Plant;
use crate::rng::PixelRng;
use accel::{Accel, Hit};
use camera::Camera;
use chamber::Chamber;
use glam::{Quat, Vec3};
use image::RgbImage;
use look::Look;
use materials::Materials;
use rayon::prelude::*;

/// A camera view of the plant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum View {
    /// Side view with the turntable at this angle (degrees).
    Side(f32),
    /// Top view.
    Top,
}

impl View {
    /// Parses `0`, `36`, ..., or `top`.
    pub fn parse(s: &str) -> anyhow::Result<View> {
        let s = s.trim();
        if s.eq_ignore_ascii_case("top") {
            return Ok(View::Top);
        }
        let a: f32 = s
            .parse()
            .map_err(|_| anyhow::anyhow!("view {s:?} is neither an angle in degrees nor `top`"))?;
        if !(0.0..360.0).contains(&a) {
            anyhow::bail!("view angle {a} must lie in [0, 360)");
        }
        Ok(View::Side(a))
    }

    /// Name used in file names and manifests (`108`, `top`).
    pub fn name(&self) -> String {
        match self {
            View::Side(a) if a.fract() == 0.0 => format!("{}", *a as i32),
            View::Side(a) => format!("{a}"),
            View::Top => "top".into(),
        }
    }
}

/// Sampling quality.
#[derive(Debug, Clone, Copy)]
pub struct Quality {
    /// Camera samples per pixel (the first passes through the pixel centre).
    pub spp: u32,
    /// Path vertices per sample (1 = direct light only).
    pub max_depth: u32,
}

impl Default for Quality {
    /// Training quality: few samples, the noise is hidden by the sensor noise
    /// and JPEG augmentation anyway.
    fn default() -> Self {
        Quality { spp: 4, max_depth: 2 }
    }
}

/// A rectangle of frame pixels to render (may extend past the frame).
#[derive(Debug, Clone, Copy)]
pub struct Window {
    /// Left column in frame pixels.
    pub x0: i32,
    /// Top row in frame pixels.
    pub y0: i32,
    /// Width.
    pub width: u32,
    /// Height.
    pub height: u32,
}

impl Window {
    /// The whole frame of `camera`, as the facility's files hold it.
    pub fn frame(camera: &Camera) -> Window {
        Window {
            x0: 0,
            y0: 0,
            width: camera.width,
            height: camera.height,
        }
    }
}

/// The plant and props with their materials: built once, rendered from many views.
pub struct Stage {
    accel: Accel,
    materials: Materials,
    bounds: (Vec3, Vec3),
}

impl Stage {
    /// Meshes props around the plant and builds the BVH.
    pub fn new(
        plant: &Plant,
        colour: &crate::plant::preset::Colour,
        panicle_rgb: [f32; 3],
        look: &Look,
    ) -> Self {
        let mut mesh = plant.mesh.clone();
        mesh.append(&chamber::props());
        let bounds = plant.mesh.bounds();
        Stage {
            accel: Accel::build(&mesh),
            materials: Materials::new(colour, plant.traits.tint, panicle_rgb, look.pot_albedo),
            bounds,
        }
    }

    /// [`Stage::new`] with the colours of `preset`; a preset without a
    /// panicle grows none, so the stand-in colour it gets is never seen.
    pub fn for_preset(plant: &Plant, preset: &Preset, look: &Look) -> Self {
        let panicle = preset
            .panicle
            .as_ref()
            .map(|x| x.reflectance)
            .unwrap_or([0.3, 0.3, 0.1]);
        Stage::new(plant, &preset.colour, panicle, look)
    }

    /// Triangles in the BVH.
    pub fn triangles(&self) -> usize {
        self.accel.len()
    }
}

/// A stage seen from one view: the turntable rotation and the chamber.
pub struct Scene<'a> {
    stage: &'a Stage,
    /// Chamber walls and lights.
    pub chamber: Chamber,
    /// Materials of the stage.
    pub materials: &'a Materials,
    to_plant: Quat,
    to_world: Quat,
    contract: &'static phyllo_contract::Contract,
}

impl<'a> Scene<'a> {
    /// The stage on the turntable at `view`, in a chamber of `look`.
    pub fn new(stage: &'a Stage, look: &Look, view: View) -> Self {
        let angle = match view {
            View::Side(a) => a.to_radians(),
            View::Top => 0.0,
        };
        let to_world = Quat::from_rotation_y(angle);
        Scene {
            stage,
            chamber: Chamber::new(look, view != View::Top),
            materials: &stage.materials,
            to_plant: to_world.inverse(),
            to_world,
            contract: phyllo_contract::Contract::embedded(),
        }
    }

    /// A plant-space point in chamber space: the turntable rotation of this view.
    #[inline]
    pub fn to_chamber(&self, p: Vec3) -> Vec3 {
        self.to_world * p
    }

    /// Closest plant/prop hit of a chamber-space ray.
    #[inline]
    pub fn hit(&self, o: Vec3, d: Vec3) -> Option<Hit> {
        let h = self
            .stage
            .accel
            .closest(self.to_plant * o, self.to_plant * d, f32::INFINITY)?;
        Some(Hit {
            normal: self.to_world * h.normal,
            ..h
        })
    }

    /// Whether the plant/props block a chamber-space segment.
    #[inline]
    pub fn occluded(&self, o: Vec3, d: Vec3, tmax: f32) -> bool {
        self.stage
            .accel
            .occluded(self.to_plant * o, self.to_plant * d, tmax)
    }

    /// Contract label value of a triangle.
    #[inline]
    pub fn label_of(&self, info: &TriInfo) -> u16 {
        if info.class == 0 {
            0
        } else {
            self.contract.encode_label(info.class, info.instance)
        }
    }

    /// Plant bounds turned into chamber space (corners of the rotated box).
    pub fn plant_corners(&self) -> Vec<Vec3> {
        let (lo, hi) = self.stage.bounds;
        (0..8)
            .map(|i| {
                let p = Vec3::new(
                    if i & 1 != 0 { hi.x } else { lo.x },
                    if i & 2 != 0 { hi.y } else { lo.y },
                    if i & 4 != 0 { hi.z } else { lo.z },
                );
                self.to_world * p
            })
            .collect()
    }
}

/// The camera for a view and look at a frame height.
pub fn camera_for(view: View, look: &Look, frame_height: u32) -> Camera {
    let k = frame_height as f32 / 514.0;
    match view {
        // Zoomed in, the camera sits lower by the same factor, so the soil
        // stays on the frame's row (the facility's zoomed frames keep the pot there).
        View::Side(_) => Camera::side(
            frame_height,
            look.cam_distance,
            look.cam_height / look.zoom,
            look.cam_shift_px * k,
        )
        .zoomed(look.zoom),
        View::Top => Camera::top(frame_height, look.top_height),
    }
}

/// Rendered pixels of a window.
pub struct Output {
    /// sRGB image.
    pub rgb: RgbImage,
    /// Panoptic label of the pixel-centre rays.
    pub label: LabelImage,
    /// Rays cast.
    pub rays: u64,
}

/// Renders `window` of the camera frame. Every pixel's random numbers depend
/// only on `seed` and its frame coordinates, so the result is the same for
/// any thread count and any window containing the pixel.
pub fn render(
    scene: &Scene,
    camera: &Camera,
    look: &Look,
    window: Window,
    quality: Quality,
    seed: u64,
) -> anyhow::Result<Output> {
    let (w, h) = (window.width as usize, window.height as usize);
    let mut rgb = vec![0u8; w * h * 3];
    let mut labels = vec![0u16; w * h];
    let spp = quality.spp.max(1);
    let rays: u64 = rgb
        .par_chunks_mut(w * 3)
        .zip(labels.par_chunks_mut(w))
        .enumerate()
        .map(|(y, (row, lrow))| {
            let fy = window.y0 + y as i32;
            let mut rays = 0u64;
            for x in 0..w {
                let fx = window.x0 + x as i32;
                let key = ((fy as i64 + (1 << 20)) as u64) << 21 | (fx as i64 + (1 << 20)) as u64;
                let mut acc = Vec3::ZERO;
                for s in 0..spp {
                    let mut r = PixelRng::new(seed, key, s);
                    // Sample 0 goes through the pixel centre: that ray is the label.
                    let (jx, jy) = if s == 0 {
                        (0.5, 0.5)
                    } else {
                        (r.uniform01(), r.uniform01())
                    };
                    let d = camera.direction(fx as f32 + jx, fy as f32 + jy);
                    let out = integrator::trace(scene, camera.position, d, &mut r, quality.max_depth);
                    if s == 0 {
                        lrow[x] = out.label;
                    }
                    acc += out.radiance;
                    rays += u64::from(out.rays);
                }
                let mut r = PixelRng::new(seed ^ 0x05ee_d0f9_015e, key, 0);
                let noise = [gauss(&mut r), gauss(&mut r), gauss(&mut r)];
                row[x * 3..x * 3 + 3].copy_from_slice(&film::develop(acc / spp as f32, look, noise));
            }
            rays
        })
        .sum();
    let mut rgb = RgbImage::from_raw(window.width, window.height, rgb).expect("buffer matches window");
    if let Some(q) = look.jpeg_quality {
        rgb = film::jpeg_round_trip(&rgb, q)?;
    }
    Ok(Output {
        rgb,
        label: LabelImage {
            width: window.width,
            height: window.height,
            data: labels,
        },
        rays,
    })
}

#[inline]
fn gauss(r: &mut PixelRng) -> f32 {
    let u1 = r.uniform01().max(1e-7);
    let u2 = r.uniform01();
    (-2.0 * u1.ln()).sqrt() * (std::f32::consts::TAU * u2).cos()
}

/// Mesh export helper: the plant plus props, for inspection.
pub fn scene_mesh(plant: &Plant) -> Mesh {
    let mut m = plant.mesh.clone();
    m.append(&chamber::props());
    m
}
