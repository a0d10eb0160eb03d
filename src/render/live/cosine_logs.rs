//! What a re-shade keeps for the next one while memory allows: for the lit
//! hits of a tile, log2 of Blinn's cosine at every light point
//! (`math::pow_log2`, the half of the tracer's power that does not depend
//! on the shininess; −∞ at a hidden point, whose term is +0 as in the
//! tracer). A later shininess edit of those hits then needs only the other
//! half (`math::pow_from_log2`) per point — no square root, no division —
//! and gives the same bits: the same operations on the same values, summed
//! in the same order.
//!
//! 4 bytes per light point of a kept hit (256 at 64 points), in batches of
//! [`LANES`] hits, point by point. They are built by the first re-shade of
//! a frame (which computes them anyway, see `respecular.rs`) in the memory
//! the records leave under the cap, tile by tile until it is used up, and
//! dropped first when a tile's records grow past the cap.

use std::sync::atomic::{AtomicUsize, Ordering};

use super::respecular::LANES;

/// A lane of a batch past its last hit.
pub const NO_HIT: u32 = u32::MAX;

/// The kept logarithms of one tile.
#[derive(Debug, Clone, Default)]
pub struct CosineLogs {
    /// Per material, whether its fully lit hits are kept (those that were
    /// re-shaded when the logs were built).
    pub materials: Vec<bool>,
    /// Per batch, its hits' indices in the tile's records ([`NO_HIT`] past
    /// the last).
    pub batches: Vec<[u32; LANES]>,
    /// Per batch, one row per light point: `logs[count·b + j][h]` is point j
    /// of lane h of batch b.
    pub logs: Vec<[f32; LANES]>,
}

impl CosineLogs {
    /// Room for `hits` kept hits of `count` light points each.
    pub fn with_room(materials: Vec<bool>, hits: usize, count: usize) -> CosineLogs {
        let batches = hits.div_ceil(LANES);
        CosineLogs {
            materials,
            batches: Vec::with_capacity(batches),
            logs: Vec::with_capacity(batches * count),
        }
    }

    /// The heap bytes of [`CosineLogs::with_room`] for these arguments.
    pub fn bytes_for(materials: usize, hits: usize, count: usize) -> usize {
        let batches = hits.div_ceil(LANES);
        materials
            + batches * size_of::<[u32; LANES]>()
            + batches * count * size_of::<[f32; LANES]>()
    }

    /// Heap bytes held.
    pub fn bytes(&self) -> usize {
        self.materials.capacity()
            + self.batches.capacity() * size_of::<[u32; LANES]>()
            + self.logs.capacity() * size_of::<[f32; LANES]>()
    }
}

/// The memory a re-shade may give to new logs, shared by its threads.
#[derive(Debug)]
pub struct LogBudget {
    left: AtomicUsize,
}

impl LogBudget {
    pub fn new(bytes: usize) -> LogBudget {
        LogBudget {
            left: AtomicUsize::new(bytes),
        }
    }

    /// Takes `bytes` if that many are left.
    pub fn take(&self, bytes: usize) -> bool {
        self.left
            .fetch_update(Ordering::Relaxed, Ordering::Relaxed, |left| {
                left.checked_sub(bytes)
            })
            .is_ok()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_budget_gives_no_more_than_it_has() {
        let budget = LogBudget::new(100);
        assert!(budget.take(60));
        assert!(!budget.take(41));
        assert!(budget.take(40));
        assert!(!budget.take(1));
    }

    #[test]
    fn room_is_counted_as_allocated() {
        let hits = 2 * LANES + 5;
        let logs = CosineLogs::with_room(vec![true; 3], hits, 64);
        assert_eq!(logs.bytes(), CosineLogs::bytes_for(3, hits, 64));
        // Three batches: their indices and 64 rows of logs each.
        assert_eq!(logs.bytes(), 3 + 3 * 4 * LANES + 3 * 64 * 4 * LANES);
    }
}
