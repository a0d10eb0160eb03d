use std::array::from_fn;

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

    /// [`Camera::pixel_ray`] of the `n` pixels from (x0, y) rightwards,
    /// into `out`: the same operations, so the same bits, eight pixels at
    /// a time, so that their divisions and square roots overlap instead
    /// of each waiting for the one before (on AVX2 by intrinsics,
    /// `row_rays_avx2`: the compiler does not vectorize the
    /// portable loop). Whole rays, not directions: a ray copied whole from
    /// here is read back at the offsets it was written with (a direction
    /// put into a ray on the stack was read back across two of its stores,
    /// which stalls the load).
    #[inline(always)]
    pub fn row_rays(&self, x0: u32, y: u32, n: u32, out: &mut Vec<Ray>) {
        out.clear();
        #[cfg(target_arch = "x86_64")]
        if super::math::avx2_kernels() {
            // SAFETY: the CPU has AVX2 (`avx2_kernels` checks).
            unsafe { self.row_rays_avx2(x0, y, n, out) };
            return;
        }
        let (w, h) = (self.width as f64, self.height as f64);
        let sy = 1.0 - 2.0 * (y as f64 + 0.5) / h;
        let (f, r, u) = (self.forward, self.right, self.up);
        for start in (x0..x0 + n).step_by(CHUNK) {
            let sx: [f64; CHUNK] = from_fn(|k| 2.0 * ((start + k as u32) as f64 + 0.5) / w - 1.0);
            let dx: [f64; CHUNK] = from_fn(|k| f.x + r.x * sx[k] + u.x * sy);
            let dy: [f64; CHUNK] = from_fn(|k| f.y + r.y * sx[k] + u.y * sy);
            let dz: [f64; CHUNK] = from_fn(|k| f.z + r.z * sx[k] + u.z * sy);
            let inv: [f64; CHUNK] =
                from_fn(|k| 1.0 / (dx[k] * dx[k] + dy[k] * dy[k] + dz[k] * dz[k]).sqrt());
            let len = CHUNK.min((x0 + n - start) as usize);
            out.extend((0..len).map(|k| {
                let dir = DVec3::new(dx[k] * inv[k], dy[k] * inv[k], dz[k] * inv[k]);
                Ray::new(self.origin, dir)
            }));
        }
    }

    /// [`Camera::row_rays`] four rays to an instruction: the compiler kept
    /// the portable loop's lanes one ray at a time, each ray's three
    /// divisions and square roots waiting on the last ray's. The same
    /// operations in the same order (no fused multiply-adds), so the same
    /// bits.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    #[inline]
    fn row_rays_avx2(&self, x0: u32, y: u32, n: u32, out: &mut Vec<Ray>) {
        use std::arch::x86_64::*;
        let (w, h) = (self.width as f64, self.height as f64);
        let sy = 1.0 - 2.0 * (y as f64 + 0.5) / h;
        let (f, r, u) = (self.forward, self.right, self.up);
        let splat = _mm256_set1_pd;
        let (two, half, one) = (splat(2.0), splat(0.5), splat(1.0));
        let width = splat(w);
        // f + r·sx + u·sy, left to right, for each coordinate.
        let axis = |f: f64, r: f64, u: f64, sx: __m256d| {
            _mm256_add_pd(
                _mm256_add_pd(splat(f), _mm256_mul_pd(splat(r), sx)),
                splat(u * sy),
            )
        };
        for start in (x0..x0 + n).step_by(CHUNK) {
            let mut dirs = [[0.0f64; CHUNK]; 3];
            for quad in 0..CHUNK / 4 {
                // Columns below 2³¹ (an image is at most 16384 wide).
                let first = (start + 4 * quad as u32) as i32;
                let column =
                    _mm256_cvtepi32_pd(_mm_setr_epi32(first, first + 1, first + 2, first + 3));
                let sx = _mm256_sub_pd(
                    _mm256_div_pd(_mm256_mul_pd(two, _mm256_add_pd(column, half)), width),
                    one,
                );
                let (dx, dy, dz) = (
                    axis(f.x, r.x, u.x, sx),
                    axis(f.y, r.y, u.y, sx),
                    axis(f.z, r.z, u.z, sx),
                );
                let squares = _mm256_add_pd(
                    _mm256_add_pd(_mm256_mul_pd(dx, dx), _mm256_mul_pd(dy, dy)),
                    _mm256_mul_pd(dz, dz),
                );
                let inv = _mm256_div_pd(one, _mm256_sqrt_pd(squares));
                for (dir, d) in dirs.iter_mut().zip([dx, dy, dz]) {
                    let lanes = &mut dir[4 * quad..4 * quad + 4];
                    // SAFETY: `lanes` holds the four f64s stored.
                    unsafe { _mm256_storeu_pd(lanes.as_mut_ptr(), _mm256_mul_pd(d, inv)) };
                }
            }
            let len = CHUNK.min((x0 + n - start) as usize);
            out.extend(
                (0..len)
                    .map(|k| Ray::new(self.origin, DVec3::new(dirs[0][k], dirs[1][k], dirs[2][k]))),
            );
        }
    }
}

/// Camera rays computed at once by [`Camera::row_rays`].
const CHUNK: usize = 8;

#[cfg(test)]
mod tests {
    use crate::render::scene::Loaded;

    #[test]
    fn a_row_of_rays_is_each_pixel_ray_s() {
        let mut camera = Loaded::seed_room().scene.camera.clone();
        for (width, height) in [(960, 540), (37, 11), (1, 1)] {
            camera.width = width;
            camera.height = height;
            let mut rays = Vec::new();
            for (x0, y, n) in [
                (0, 0, width),
                (width - 1, height - 1, 1),
                (width / 3, height / 2, width / 2),
            ] {
                camera.row_rays(x0, y, n, &mut rays);
                let got: Vec<_> = rays.iter().map(|r| (r.origin, r.dir)).collect();
                let want: Vec<_> = (x0..x0 + n)
                    .map(|x| camera.pixel_ray(x, y))
                    .map(|r| (r.origin, r.dir))
                    .collect();
                assert_eq!(got, want, "{width}×{height}: {n} from ({x0}, {y})");
            }
        }
    }
}
