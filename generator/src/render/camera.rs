//! The facility's calibrated cameras: a side camera about 5.5 units from the
//! plant axis, looking horizontally at the pot with a 15.25° vertical field
//! of view and a 1.1936 frame aspect; and a top camera about 3 units above.
//! Rays are generated for frame pixel coordinates, which may lie outside the
//! frame (a crop padded with more of the chamber).

use glam::Vec3;

/// Vertical field of view of the LemnaTec camera, degrees.
pub const VFOV_DEG: f32 = 15.25;
/// Frame width / height of the LemnaTec camera (2454 x 2056).
pub const FRAME_ASPECT: f32 = 2454.0 / 2056.0;
/// Side camera distance from the plant axis (facility units).
pub const SIDE_DISTANCE: f32 = 5.5;
/// Side camera height above the soil surface, from the pot's place in real frames.
pub const SIDE_HEIGHT: f32 = 0.44;
/// Top camera height above the soil surface.
pub const TOP_HEIGHT: f32 = 3.0;
/// Vertical field of view of the top camera, degrees. The side camera's
/// 15.25° from 3 units above shows only 0.8 units of floor, less at leaf
/// height: the leaves of 60 % of top views ran off a 512 crop. At 30° 17 %
/// do (the longest blades of the oldest plants), and the youngest plants'
/// leaves stay several pixels wide (models/EXPERIMENTS.md, "The top
/// camera's framing").
pub const TOP_VFOV_DEG: f32 = 30.0;

/// A pinhole camera.
#[derive(Debug, Clone, Copy)]
pub struct Camera {
    /// Centre of projection.
    pub position: Vec3,
    /// Image-right direction.
    pub right: Vec3,
    /// Image-up direction.
    pub up: Vec3,
    /// Viewing direction.
    pub forward: Vec3,
    /// Focal length in pixels.
    pub focal_px: f32,
    /// Principal point, frame pixels.
    pub cx: f32,
    /// Principal point, frame pixels.
    pub cy: f32,
    /// Frame width in pixels.
    pub width: u32,
    /// Frame height in pixels.
    pub height: u32,
}

/// Frame width for a frame height at the facility aspect.
pub fn frame_width(height: u32) -> u32 {
    (height as f32 * FRAME_ASPECT).round() as u32
}

impl Camera {
    fn focal(height: u32) -> f32 {
        Self::focal_for(height, VFOV_DEG)
    }

    fn focal_for(height: u32, vfov_deg: f32) -> f32 {
        0.5 * height as f32 / (0.5 * vfov_deg.to_radians()).tan()
    }

    /// Side camera; `distance`, `height` and `shift_px` (principal point
    /// offset, frame pixels at this resolution) allow jitter.
    pub fn side(frame_height: u32, distance: f32, height: f32, shift_px: f32) -> Self {
        let width = frame_width(frame_height);
        Camera {
            position: Vec3::new(0.0, height, distance),
            right: Vec3::X,
            up: Vec3::Y,
            forward: Vec3::NEG_Z,
            focal_px: Self::focal(frame_height),
            cx: 0.5 * width as f32 + shift_px,
            cy: 0.5 * frame_height as f32,
            width,
            height: frame_height,
        }
    }

    /// The same camera with its focal length multiplied by `zoom`.
    pub fn zoomed(mut self, zoom: f32) -> Self {
        self.focal_px *= zoom;
        self
    }

    /// Top camera looking straight down; image-up points to the back wall.
    pub fn top(frame_height: u32, height: f32) -> Self {
        let width = frame_width(frame_height);
        Camera {
            position: Vec3::new(0.0, height, 0.0),
            right: Vec3::X,
            up: Vec3::NEG_Z,
            forward: Vec3::NEG_Y,
            focal_px: Self::focal_for(frame_height, TOP_VFOV_DEG),
            cx: 0.5 * width as f32,
            cy: 0.5 * frame_height as f32,
            width,
            height: frame_height,
        }
    }

    /// Unit ray direction through frame pixel coordinates (x right, y down).
    #[inline]
    pub fn direction(&self, px: f32, py: f32) -> Vec3 {
        let x = (px - self.cx) / self.focal_px;
        let y = (self.cy - py) / self.focal_px;
        (self.forward + self.right * x + self.up * y).normalize()
    }

    /// Frame pixel coordinates of a world point, if it is in front.
    pub fn project(&self, p: Vec3) -> Option<(f32, f32)> {
        let d = p - self.position;
        let z = d.dot(self.forward);
        if z <= 1e-6 {
            return None;
        }
        Some((
            self.cx + self.focal_px * d.dot(self.right) / z,
            self.cy - self.focal_px * d.dot(self.up) / z,
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn contract_frame_is_614_by_514() {
        assert_eq!(frame_width(514), 614);
        let c = Camera::side(514, SIDE_DISTANCE, SIDE_HEIGHT, 0.0);
        let (x, y) = c.project(Vec3::new(0.0, SIDE_HEIGHT, 0.0)).unwrap();
        assert!((x - 307.0).abs() < 1e-3 && (y - 257.0).abs() < 1e-3);
        let d = c.direction(x, y);
        assert!((d - Vec3::NEG_Z).length() < 1e-5);
    }
}
