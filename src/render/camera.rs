use glam::DVec3;

use super::geometry::Ray;
use super::scene_file::CameraDesc;

/// Pinhole camera; one ray through the centre of each pixel.
#[derive(Debug, Clone)]
pub struct Camera {
    pub origin: DVec3,
    forward: DVec3,
    /// Image right: `forward × up`, scaled by the half-width of the view.
    right: DVec3,
    /// Image up, scaled by the half-height of the view.
    up: DVec3,
    pub width: u32,
    pub height: u32,
}

impl Camera {
    /// Builds the camera of a validated description.
    pub fn new(desc: &CameraDesc) -> Camera {
        let origin = DVec3::from(desc.position);
        let forward = super::math::normalize_robust(DVec3::from(desc.look_at) - origin);
        let right = forward
            .cross(super::math::normalize_robust(DVec3::from(desc.up)))
            .normalize();
        let up = right.cross(forward);
        let half_h = (desc.fov_y_deg.to_radians() * 0.5).tan();
        let half_w = half_h * desc.width as f64 / desc.height as f64;
        Camera {
            origin,
            forward,
            right: right * half_w,
            up: up * half_h,
            width: desc.width,
            height: desc.height,
        }
    }

    /// Ray through image position (x, y) in pixels, (0, 0) the top-left
    /// corner of the image: pixel (i, j)'s centre is (i + 0.5, j + 0.5).
    pub fn ray(&self, x: f64, y: f64) -> Ray {
        let sx = 2.0 * x / self.width as f64 - 1.0;
        let sy = 1.0 - 2.0 * y / self.height as f64;
        Ray::new(
            self.origin,
            (self.forward + self.right * sx + self.up * sy).normalize(),
        )
    }

    pub fn pixel_ray(&self, px: u32, py: u32) -> Ray {
        self.ray(px as f64 + 0.5, py as f64 + 0.5)
    }
}
