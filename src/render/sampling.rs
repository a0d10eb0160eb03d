//! Where shadow rays meet the light: points in the light's (a, b) ∈ \[0,1\]²
//! coordinates, by pattern.

use super::rng::Rng;
use super::scene_file::Sampling;
use super::sobol::{rotated_grid, scrambled_point, sobol_table};

/// Side of the grid used by the grid-based patterns: ⌊√shadow_rays⌋.
pub fn grid_side(shadow_rays: u32) -> u32 {
    (shadow_rays.max(1) as f64).sqrt().floor() as u32
}

/// Number of light points (shadow rays) per hit point.
pub fn points_per_hit(sampling: Sampling, shadow_rays: u32) -> usize {
    let n = grid_side(shadow_rays) as usize;
    match sampling {
        Sampling::Grid | Sampling::Stratified | Sampling::RotatedGrid => n * n,
        Sampling::Random | Sampling::Sobol => shadow_rays.max(1) as usize,
        Sampling::Mixed => 2 * n * n,
    }
}

/// A sampling pattern at a given shadow-ray count.
#[derive(Debug, Clone)]
pub struct Pattern {
    pub sampling: Sampling,
    pub shadow_rays: u32,
    side: u32,
    count: usize,
    /// Unscrambled Sobol' points, for the `sobol` pattern.
    sobol: Vec<(u32, u32)>,
}

impl Pattern {
    pub fn new(sampling: Sampling, shadow_rays: u32) -> Pattern {
        Pattern {
            sampling,
            shadow_rays,
            side: grid_side(shadow_rays),
            count: points_per_hit(sampling, shadow_rays),
            sobol: if sampling == Sampling::Sobol {
                sobol_table(points_per_hit(sampling, shadow_rays))
            } else {
                Vec::new()
            },
        }
    }

    /// Light points per hit point.
    pub fn count(&self) -> usize {
        self.count
    }

    /// Writes the points of one hit point into `a` and `b` (each at least
    /// `count()` long), drawing any random numbers from `rng`.
    pub fn fill(&self, rng: &mut Rng, a: &mut [f32], b: &mut [f32]) {
        let n = self.side as usize;
        let inv = 1.0 / n as f32;
        let grid = |a: &mut [f32], b: &mut [f32], jitter: Option<&mut Rng>| {
            let mut k = 0;
            match jitter {
                None => {
                    for j in 0..n {
                        for i in 0..n {
                            a[k] = (i as f32 + 0.5) * inv;
                            b[k] = (j as f32 + 0.5) * inv;
                            k += 1;
                        }
                    }
                }
                Some(rng) => {
                    for j in 0..n {
                        for i in 0..n {
                            a[k] = (i as f32 + rng.next_f32()) * inv;
                            b[k] = (j as f32 + rng.next_f32()) * inv;
                            k += 1;
                        }
                    }
                }
            }
        };
        match self.sampling {
            Sampling::Grid => grid(a, b, None),
            Sampling::Stratified => grid(a, b, Some(rng)),
            Sampling::Random => {
                for k in 0..self.count {
                    a[k] = rng.next_f32();
                    b[k] = rng.next_f32();
                }
            }
            Sampling::Mixed => {
                grid(a, b, None);
                for k in n * n..self.count {
                    a[k] = rng.next_f32();
                    b[k] = rng.next_f32();
                }
            }
            Sampling::Sobol => {
                let seeds = rng.next_u64();
                let (sx, sy) = (seeds as u32, (seeds >> 32) as u32);
                for (k, &entry) in self.sobol.iter().enumerate() {
                    (a[k], b[k]) = scrambled_point(entry, sx, sy);
                }
            }
            Sampling::RotatedGrid => {
                let (su, sv) = (rng.next_f32(), rng.next_f32());
                let mut k = 0;
                for j in 0..n as u32 {
                    for i in 0..n as u32 {
                        (a[k], b[k]) = rotated_grid(n as u32, i, j, su, sv);
                        k += 1;
                    }
                }
            }
        }
    }

    /// Whether every hit point gets the same points (no random numbers).
    pub fn is_fixed(&self) -> bool {
        self.sampling == Sampling::Grid
    }
}
