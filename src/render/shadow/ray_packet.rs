//! Up to 64 shadow rays of one hit point as a bit set, with their light
//! points binned on a coarse grid so that "which rays end inside this
//! rectangle of the light's plane" costs a few bit operations.

use super::light_frame::{Footprints, LightFrame};

/// Rays per packet: one bit each in a `u64`.
pub const PACKET: usize = 64;
/// Cells per axis of the binning grid.
const CELLS: usize = 8;

/// The light points of one packet, binned per axis of the light's plane.
#[derive(Debug, Clone, Default)]
pub struct RayBins {
    /// Smallest coordinate of the packet's light points, per axis.
    min: [f64; 2],
    /// Cells per unit length, per axis: the largest point falls just short
    /// of cell `CELLS`.
    scale: [f64; 2],
    /// `below[axis][c]`: the rays whose light point lies in a cell < c.
    below: [[u64; CELLS + 1]; 2],
    /// Every ray of the packet.
    pub all: u64,
}

impl RayBins {
    /// Bins the light points (a\[j\], b\[j\]), at most [`PACKET`] of them.
    // Lanes of parallel arrays: index loops are what vectorizes.
    #[allow(clippy::needless_range_loop)]
    pub fn new(frame: &LightFrame, a: &[f32], b: &[f32]) -> RayBins {
        debug_assert!(a.len() <= PACKET && a.len() == b.len());
        let mut min = [f64::INFINITY; 2];
        let mut max = [f64::NEG_INFINITY; 2];
        let mut points = [[0.0; 2]; PACKET];
        for (j, (&a, &b)) in a.iter().zip(b).enumerate() {
            points[j] = frame.light_point(a as f64, b as f64);
            for axis in 0..2 {
                min[axis] = min[axis].min(points[j][axis]);
                max[axis] = max[axis].max(points[j][axis]);
            }
        }
        let mut bins = RayBins {
            min,
            ..RayBins::default()
        };
        for axis in 0..2 {
            // (max − min)·scale ≤ 8·(1 − 2⁻²⁰)·(1 + 2⁻⁵²) < 8.
            let scale = CELLS as f64 * (1.0 - 1.0 / (1u64 << 20) as f64) / (max[axis] - min[axis]);
            bins.scale[axis] = if scale.is_finite() { scale } else { 1.0 };
        }
        let mut cells = [[0u64; CELLS]; 2];
        for (j, point) in points[..a.len()].iter().enumerate() {
            for axis in 0..2 {
                cells[axis][bins.cell(axis, point[axis]).min(CELLS - 1)] |= 1 << j;
            }
        }
        for axis in 0..2 {
            for c in 0..CELLS {
                bins.below[axis][c + 1] = bins.below[axis][c] | cells[axis][c];
            }
        }
        bins.all = bins.below[0][CELLS];
        bins
    }

    /// The cell of a light point's coordinate: the same monotone function
    /// as for rectangle ends in [`rays_in4`](Self::rays_in4), so a point
    /// inside a rectangle always falls in a cell inside the rectangle's
    /// cell range.
    #[inline(always)]
    fn cell(&self, axis: usize, v: f64) -> usize {
        clamp_cell((v - self.min[axis]) * self.scale[axis]) as usize
    }

    /// The rays whose light point may lie inside the rectangle
    /// `[x0, x1, y0, y1]`: [`rays_in4`](Self::rays_in4) for one, its
    /// four ends as lanes.
    // Lanes of parallel arrays: index loops are what vectorizes.
    #[allow(clippy::needless_range_loop)]
    #[inline(always)]
    pub fn rays_in_rect(&self, rect: [f64; 4]) -> u64 {
        let min = [self.min[0], self.min[0], self.min[1], self.min[1]];
        let scale = [self.scale[0], self.scale[0], self.scale[1], self.scale[1]];
        let mut cell = [0i32; 4];
        for k in 0..4 {
            cell[k] = clamp_cell((rect[k] - min[k]) * scale[k] + (k % 2) as f64);
        }
        let [bx, by] = &self.below;
        let at = |table: &[u64; CELLS + 1], cell: i32| {
            // SAFETY: a clamped cell lies in 0..=CELLS, the table's indices.
            unsafe { *table.get_unchecked(cell as usize) }
        };
        at(bx, cell[1]) & !at(bx, cell[0]) & at(by, cell[3]) & !at(by, cell[2])
    }

    /// For each of four rectangles, the rays whose light point may lie
    /// inside it (all that do, and possibly some near it; none for an empty
    /// one). The cell arithmetic vectorizes; the table lookups stay scalar. A
    /// rectangle
    /// end maps to cell(lo) and ⌊·⌋ + 1 of hi's cell coordinate: 0 for a
    /// rectangle wholly below the points.
    // Lanes of parallel arrays: index loops are what vectorizes.
    #[allow(clippy::needless_range_loop)]
    #[inline(always)]
    pub fn rays_in4(&self, f: &Footprints) -> [u64; 4] {
        // Cell coordinates, clamped and converted four lanes at a time.
        let mut cell = [[0i32; 4]; 4];
        for s in 0..4 {
            cell[0][s] = clamp_cell((f.x0[s] - self.min[0]) * self.scale[0]);
            cell[1][s] = clamp_cell((f.x1[s] - self.min[0]) * self.scale[0] + 1.0);
            cell[2][s] = clamp_cell((f.y0[s] - self.min[1]) * self.scale[1]);
            cell[3][s] = clamp_cell((f.y1[s] - self.min[1]) * self.scale[1] + 1.0);
        }
        // Most rectangles lie beside the packet's points: one whose high
        // ends fall in no cell above the lowest, or its low ends in the
        // last, holds no ray (its table entries are 0 and all).
        let top = CELLS as i32;
        let mut empty = [false; 4];
        for s in 0..4 {
            empty[s] =
                (cell[1][s] == 0) | (cell[0][s] == top) | (cell[3][s] == 0) | (cell[2][s] == top);
        }
        if empty == [true; 4] {
            return [0; 4];
        }
        let [bx, by] = &self.below;
        let at = |table: &[u64; CELLS + 1], cell: i32| {
            // SAFETY: a clamped cell lies in 0..=CELLS, the table's indices.
            unsafe { *table.get_unchecked(cell as usize) }
        };
        let mut rays = [0u64; 4];
        for s in 0..4 {
            // Every table entry lies within the packet's rays.
            rays[s] =
                at(bx, cell[1][s]) & !at(bx, cell[0][s]) & at(by, cell[3][s]) & !at(by, cell[2][s]);
        }
        rays
    }
}

/// ⌊c⌋ clamped to 0..=CELLS (NaN to 0): a comparison for the lower end
/// and `min` (a vector instruction) for the upper, then an in-range
/// conversion. (A comparison and select for the upper end lets the
/// compiler move it past the conversion, where a node's sixteen cells no
/// longer vectorize; `max` for the lower end costs a face's rectangle its
/// vector form.)
#[inline(always)]
fn clamp_cell(c: f64) -> i32 {
    let c = if c > 0.0 { c } else { 0.0 };
    let c = c.min(CELLS as f64);
    // SAFETY: c is in [0, CELLS], finite and not NaN. (A signed conversion:
    // the one with a vector instruction.)
    unsafe { c.to_int_unchecked::<i32>() }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A rectangle of the light's plane.
    #[derive(Debug, Clone, Copy)]
    struct Footprint {
        x: [f64; 2],
        y: [f64; 2],
        near: f64,
    }

    impl RayBins {
        /// The rays in one rectangle: the first lane of four.
        fn rays_in(&self, f: &Footprint) -> u64 {
            let (inf, ninf) = (f64::INFINITY, f64::NEG_INFINITY);
            let four = Footprints {
                x0: [f.x[0], inf, inf, inf],
                x1: [f.x[1], ninf, ninf, ninf],
                y0: [f.y[0], inf, inf, inf],
                y1: [f.y[1], ninf, ninf, ninf],
                near: [f.near; 4],
            };
            self.rays_in4(&four)[0]
        }
    }
    use crate::render::Loaded;

    #[test]
    fn rays_in_holds_exactly_the_points_of_whole_cells_and_never_misses_one() {
        let frame = LightFrame::new(&Loaded::seed_room().scene.light);
        let mut rng = crate::render::rng::Rng::new(7);
        let mut uniform = || (rng.next_u64() >> 40) as f32 / (1u64 << 24) as f32;
        let (a, b): (Vec<f32>, Vec<f32>) = (0..PACKET).map(|_| (uniform(), uniform())).unzip();
        let bins = RayBins::new(&frame, &a, &b);
        assert_eq!(bins.all, u64::MAX);
        let points: Vec<[f64; 2]> = (0..PACKET)
            .map(|j| frame.light_point(a[j] as f64, b[j] as f64))
            .collect();
        let mut seen = 0;
        for k in 0..2000 {
            let t = |i: u64| (((k * 7919 + i * 104729) % 1000) as f64 / 1000.0) * 3.0 - 0.5;
            let (x0, y0) = (t(1), t(2));
            let f = Footprint {
                x: [x0, x0 + t(3).abs() * 0.3],
                y: [y0, y0 + t(4).abs() * 0.3],
                near: 0.0,
            };
            let rays = bins.rays_in(&f);
            for (j, p) in points.iter().enumerate() {
                let inside = (f.x[0]..=f.x[1]).contains(&p[0]) && (f.y[0]..=f.y[1]).contains(&p[1]);
                if inside {
                    assert!(rays & (1 << j) != 0, "ray {j} at {p:?} missed by {f:?}");
                    seen += 1;
                }
            }
        }
        assert!(seen > 100, "{seen}");
        // A rectangle beside the light holds none.
        let beside = Footprint {
            x: [10.0, 11.0],
            y: [0.0, 1.0],
            near: 0.0,
        };
        assert_eq!(bins.rays_in(&beside), 0);
        let before = Footprint {
            x: [-11.0, -10.0],
            ..beside
        };
        assert_eq!(bins.rays_in(&before), 0);
        let empty = Footprint {
            x: [f64::INFINITY, f64::NEG_INFINITY],
            y: [f64::INFINITY, f64::NEG_INFINITY],
            near: 0.0,
        };
        assert_eq!(bins.rays_in(&empty), 0);
        // Ends beyond every cell clamp to the first and last: the whole
        // plane holds every ray, as a face's rectangle does.
        let everywhere = Footprint {
            x: [f64::NEG_INFINITY, f64::INFINITY],
            y: [-1e300, 1e300],
            near: 0.0,
        };
        assert_eq!(bins.rays_in(&everywhere), u64::MAX);
        let [x, y] = [everywhere.x, everywhere.y];
        assert_eq!(bins.rays_in_rect([x[0], x[1], y[0], y[1]]), u64::MAX);
    }

    #[test]
    fn a_grid_pattern_bins_one_point_per_cell() {
        let frame = LightFrame::new(&Loaded::seed_room().scene.light);
        let (mut a, mut b) = (Vec::new(), Vec::new());
        for j in 0..8 {
            for i in 0..8 {
                a.push((i as f32 + 0.5) / 8.0);
                b.push((j as f32 + 0.5) / 8.0);
            }
        }
        let bins = RayBins::new(&frame, &a, &b);
        // The rectangle around the point (i, j) = (2, 5) alone.
        let [x, y] = frame.light_point(2.5 / 8.0, 5.5 / 8.0);
        let [x1, y1] = frame.light_point(2.6 / 8.0, 5.6 / 8.0);
        let f = Footprint {
            x: [x.min(x1), x.max(x1)],
            y: [y.min(y1), y.max(y1)],
            near: 0.0,
        };
        assert_eq!(bins.rays_in(&f), 1 << (5 * 8 + 2));
    }
}
