//! Domain randomisation: everything about the chamber, light and camera that
//! varies between images so a model does not learn one chamber only. The
//! facility look is the centre of every distribution.

use crate::rng::{self, Draw};
use rand::Rng;

/// Appearance and camera settings of one image.
#[derive(Debug, Clone)]
pub struct Look {
    /// Multiplier from scene radiance to sensor value.
    pub exposure: f32,
    /// White-balance gains applied by the "camera".
    pub white_balance: [f32; 3],
    /// Colour of the lamps (correlated colour temperature as RGB gains).
    pub light_tint: [f32; 3],
    /// Radiance of the back wall.
    pub back_wall: f32,
    /// Radiance of the translucent side panels.
    pub side_panels: f32,
    /// Radiance of the ceiling lamps.
    pub ceiling: f32,
    /// Side camera distance from the plant axis.
    pub cam_distance: f32,
    /// Side camera height above the soil.
    pub cam_height: f32,
    /// Principal point shift, in pixels of a 514-high frame.
    pub cam_shift_px: f32,
    /// Top camera height above the soil.
    pub top_height: f32,
    /// Pot albedo.
    pub pot_albedo: [f32; 3],
    /// Floor albedo.
    pub floor_albedo: [f32; 3],
    /// Standard deviation of Gaussian sensor noise (in `[0, 1]` sRGB units).
    pub noise_sd: f32,
    /// JPEG round trip quality, if the image should carry JPEG artefacts.
    pub jpeg_quality: Option<u8>,
    /// Seed of the chamber fittings' layout; `None` is the facility layout.
    pub fittings: Option<u64>,
    /// Optical zoom of the side camera (1: the calibrated field of view).
    /// The camera is lowered with it so that the pot stays where it is in
    /// the frame, as in the facility's zoomed frames.
    pub zoom: f32,
}

impl Look {
    /// The facility as calibrated against the real dev images.
    pub fn facility() -> Self {
        Look {
            exposure: 1.35,
            white_balance: [1.0, 1.0, 1.0],
            light_tint: [1.0, 0.98, 0.9],
            back_wall: 1.0,
            side_panels: 0.85,
            ceiling: 1.2,
            cam_distance: super::camera::SIDE_DISTANCE,
            cam_height: super::camera::SIDE_HEIGHT,
            cam_shift_px: 20.0,
            top_height: super::camera::TOP_HEIGHT,
            pot_albedo: [0.85, 0.85, 0.82],
            floor_albedo: [0.8, 0.77, 0.72],
            noise_sd: 0.008,
            jpeg_quality: None,
            fittings: None,
            zoom: 1.0,
        }
    }

    /// A facility look perturbed by draws from `seed` (same seed, same look).
    pub fn randomised(seed: u64) -> Self {
        let mut r = rng::stream(seed, "look", 0);
        let base = Look::facility();
        // Colour temperature as a warm/cool axis on the lamp colour.
        let warm = r.uniform(-1.0, 1.0);
        let light_tint = [1.0 + 0.05 * warm, 0.98, 0.9 - 0.12 * warm];
        let wb_err = [r.normal(1.0, 0.04), 1.0, r.normal(1.0, 0.05)];
        Look {
            exposure: base.exposure * r.uniform(0.8, 1.25),
            white_balance: wb_err,
            light_tint,
            back_wall: base.back_wall * r.uniform(0.85, 1.1),
            side_panels: base.side_panels * r.uniform(0.7, 1.1),
            ceiling: base.ceiling * r.uniform(0.6, 1.4),
            // Now and then a closer camera, as in older frames of the facility.
            cam_distance: if r.chance(0.12) {
                r.uniform(3.4, 4.8)
            } else {
                base.cam_distance + r.normal(0.0, 0.12)
            },
            cam_height: base.cam_height + r.normal(0.0, 0.04),
            cam_shift_px: base.cam_shift_px + r.normal(0.0, 12.0),
            top_height: base.top_height + r.normal(0.0, 0.1),
            pot_albedo: {
                let g = r.uniform(0.7, 0.9);
                [g, g, g * r.uniform(0.92, 1.0)]
            },
            floor_albedo: {
                let g = r.uniform(0.6, 0.85);
                [g, g * 0.97, g * 0.92]
            },
            noise_sd: r.uniform(0.002, 0.02),
            jpeg_quality: if r.chance(0.5) {
                Some(r.uniform(70.0, 95.0) as u8)
            } else {
                None
            },
            fittings: Some(r.random::<u64>()),
            zoom: base.zoom,
        }
    }
}
