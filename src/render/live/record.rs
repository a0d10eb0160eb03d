//! What a full-quality render keeps of every pixel so that a later edit
//! of a shading parameter needs no ray: the hits of its path, their light
//! factors, and what recomputing the specular factor needs.
//!
//! Bytes per hit: 12 for the colour tier (material, diffuse and specular
//! factors) — enough for every recombine edit and for reflectivity — plus
//! 12 for the ray tier (the object met and its distance along the ray:
//! what a light edit needs to follow the path without intersecting, see
//! `relight.rs`), plus 36 + 8 per 64 light points for the shininess tier
//! (the hit's light direction, normal and view in f32, and one visibility
//! bit per light point). Per pixel: 5 (its first hit and how its path
//! ended). At 960×540, 64 shadow rays, depth 4 on the seed room (575 k
//! hits): about 42 MB.

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};

use glam::Vec3;

use super::cosine_logs::CosineLogs;
use crate::render::progressive::{TileRect, lock};
use crate::render::shading::LightTerms;
use crate::render::shading_params::ShadingParams;
use crate::render::shadow::{ShadowBuffers, live_rays};
use crate::render::tracer::{HitRecord, PathEnd, PathSink};

/// The colour tier of one hit.
#[derive(Debug, Clone, Copy)]
pub struct ColourHit {
    pub material: u32,
    pub factors: LightTerms,
}

/// The shininess tier of one hit.
#[derive(Debug, Clone, Copy)]
pub struct ShapeHit {
    pub to_light: Vec3,
    pub normal: Vec3,
    pub view: Vec3,
}

/// The records of one tile's paths: pixel by pixel, row by row, each
/// pixel's camera samples in order.
#[derive(Debug, Clone)]
pub struct TileRecord {
    pub rect: TileRect,
    /// Per path, the index of its first hit; one more entry at the end.
    pub starts: Vec<u32>,
    pub ends: Vec<PathEnd>,
    pub hits: Vec<ColourHit>,
    /// The ray tier, parallel to `hits`: the object each hit's ray met and
    /// at what distance along it.
    pub objects: Vec<u32>,
    pub distances: Vec<f64>,
    /// The shininess tier, parallel to `hits` (absent above the memory cap).
    pub shapes: Option<Shapes>,
    /// Per material, the shininess the specular factors were computed
    /// with: each tile knows its own, so that a re-shade cancelled half-way
    /// leaves every tile consistent (shared between tiles, not counted).
    pub shininess: Arc<[f32]>,
    /// What a re-shade kept for the next one (see `cosine_logs.rs`).
    pub logs: Option<CosineLogs>,
}

/// The shininess tier of a tile.
#[derive(Debug, Clone, Default)]
pub struct Shapes {
    pub hits: Vec<ShapeHit>,
    /// `words` visibility words per hit.
    pub visible: Vec<u64>,
    pub words: usize,
}

impl Shapes {
    fn with_room(hits: usize, words: usize) -> Shapes {
        Shapes {
            hits: Vec::with_capacity(hits),
            visible: Vec::with_capacity(hits * words),
            words,
        }
    }
}

impl TileRecord {
    pub fn new(
        rect: TileRect,
        light_points: usize,
        with_shapes: bool,
        shininess: Arc<[f32]>,
    ) -> TileRecord {
        let pixels = (rect.w * rect.h) as usize;
        let mut starts = Vec::with_capacity(pixels + 1);
        starts.push(0);
        // Room for two hits a pixel (a mirror's paths have more): growing
        // copies what is there, and `shrink` gives the rest back in place.
        let hits = 2 * pixels;
        TileRecord {
            rect,
            starts,
            ends: Vec::with_capacity(pixels),
            hits: Vec::with_capacity(hits),
            objects: Vec::with_capacity(hits),
            distances: Vec::with_capacity(hits),
            shapes: with_shapes.then(|| Shapes::with_room(hits, light_points.div_ceil(64))),
            shininess,
            logs: None,
        }
    }

    /// `self`'s buffers, emptied, as the record of tile `rect` (see
    /// [`Budget::record`]); they grow as [`TileRecord::new`]'s do.
    fn reused(
        mut self,
        rect: TileRect,
        light_points: usize,
        with_shapes: bool,
        shininess: Arc<[f32]>,
    ) -> TileRecord {
        self.rect = rect;
        self.starts.clear();
        self.starts.push(0);
        self.ends.clear();
        self.hits.clear();
        self.objects.clear();
        self.distances.clear();
        let words = light_points.div_ceil(64);
        self.shapes = match (with_shapes, self.shapes.take()) {
            (false, _) => None,
            (true, Some(mut shapes)) => {
                shapes.hits.clear();
                shapes.visible.clear();
                shapes.words = words;
                Some(shapes)
            }
            (true, None) => Some(Shapes::with_room(2 * (rect.w * rect.h) as usize, words)),
        };
        self.shininess = shininess;
        self.logs = None;
        self
    }

    /// Heap bytes held.
    pub fn bytes(&self) -> usize {
        self.path_bytes() + self.logs.as_ref().map_or(0, CosineLogs::bytes)
    }

    /// Heap bytes held by the paths' records (all but the kept logarithms).
    pub fn path_bytes(&self) -> usize {
        let shapes = self.shapes.as_ref().map_or(0, |s| {
            s.hits.capacity() * size_of::<ShapeHit>() + s.visible.capacity() * 8
        });
        self.starts.capacity() * 4
            + self.ends.capacity() * size_of::<PathEnd>()
            + self.hits.capacity() * size_of::<ColourHit>()
            + self.objects.capacity() * 4
            + self.distances.capacity() * 8
            + shapes
    }

    /// The hits of path `p` of the tile (pixel p / spp, sample p % spp).
    #[inline]
    pub fn path_hits(&self, p: usize) -> std::ops::Range<usize> {
        self.starts[p] as usize..self.starts[p + 1] as usize
    }

    /// Gives back the spare capacity.
    pub fn shrink(&mut self) {
        self.starts.shrink_to_fit();
        self.ends.shrink_to_fit();
        self.hits.shrink_to_fit();
        self.objects.shrink_to_fit();
        self.distances.shrink_to_fit();
        if let Some(s) = &mut self.shapes {
            s.hits.shrink_to_fit();
            s.visible.shrink_to_fit();
        }
    }

    /// Drops the shininess tier and the spare capacity.
    pub fn drop_shapes(&mut self) {
        self.shapes = None;
        self.logs = None;
        self.shrink();
    }
}

/// The shininess of every material, as the records keep it.
pub fn shininess_of(shading: &ShadingParams) -> Arc<[f32]> {
    shading.materials.iter().map(|m| m.shininess).collect()
}

/// Records the paths of one tile as they are traced.
pub struct TileRecorder<'a> {
    pub record: &'a mut TileRecord,
}

impl PathSink for TileRecorder<'_> {
    const RECORD: bool = true;

    // Inlined into the path's loop: passed through memory, the hit's 60
    // bytes cost more than writing them out.
    #[inline(always)]
    fn hit(&mut self, hit: HitRecord, buf: &ShadowBuffers, count: usize) -> usize {
        let r = &mut *self.record;
        let index = r.hits.len();
        r.hits.push(ColourHit {
            material: hit.material,
            factors: hit.factors,
        });
        r.objects.push(hit.object);
        r.distances.push(hit.t);
        if let Some(s) = &mut r.shapes {
            s.hits.push(ShapeHit {
                to_light: hit.to_light,
                normal: hit.normal,
                view: hit.view,
            });
            push_visibility_bits(&buf.vis, count, &mut s.visible);
        }
        index
    }

    #[inline(always)]
    fn set_factors(&mut self, index: usize, factors: LightTerms) {
        self.record.hits[index].factors = factors;
    }

    #[inline(always)]
    fn set_visible(&mut self, index: usize, bits: u64) {
        let r = &mut *self.record;
        if let Some(s) = &mut r.shapes {
            // One word a hit (at most 64 light points).
            debug_assert_eq!(s.visible.len(), r.hits.len());
            s.visible[index] = bits;
        }
    }

    #[inline]
    fn end(&mut self, end: PathEnd) {
        let r = &mut *self.record;
        r.ends.push(end);
        r.starts.push(r.hits.len() as u32);
    }
}

/// Appends one bit per light point (bit j of word j / 64) for the first
/// `count` points of `vis`, set where the point is not 0, the last word
/// padded with 0s. `vis` runs on to a multiple of 8 (as in
/// [`ShadowBuffers`]; what the padding holds is masked off): each word is
/// built in a register by the shadow packets' [`live_rays`], two SSE
/// move-masks per eight points.
#[inline]
pub fn push_visibility_bits(vis: &[f32], count: usize, out: &mut Vec<u64>) {
    for (k, points) in vis[..count.next_multiple_of(8)].chunks(64).enumerate() {
        let word = live_rays(points);
        let left = count - 64 * k;
        out.push(if left < 64 {
            word & ((1 << left) - 1)
        } else {
            word
        });
    }
}

/// The memory budget of one frame's records, shared by the threads that
/// fill them: once the cap is passed, tiles still to come keep no
/// shininess tier ([`Budget::shapes_allowed`]), and the frame then drops
/// it everywhere, or all records if the colour tier alone is over the cap
/// (`Frame::trimmed`). It also holds the records of the frame before, whose
/// buffers the new tiles take over ([`Budget::record`]).
#[derive(Debug)]
pub struct Budget {
    pub cap: usize,
    used: AtomicUsize,
    shapes: AtomicBool,
    spares: Mutex<Vec<TileRecord>>,
}

impl Budget {
    /// A budget of `cap` bytes whose tiles reuse the buffers of `spares`.
    pub fn new(cap: usize, spares: Vec<TileRecord>) -> Budget {
        Budget {
            cap,
            used: AtomicUsize::new(0),
            shapes: AtomicBool::new(true),
            spares: Mutex::new(spares),
        }
    }

    pub fn shapes_allowed(&self) -> bool {
        self.shapes.load(Ordering::Relaxed)
    }

    /// An empty record of tile `rect`, in a spare record's buffers while
    /// there is one: the frame before's pages, already mapped, instead of
    /// fresh ones (freed and mapped again, the ~60 MB of a frame's records
    /// cost a page fault every 4 kB, several per cent of a re-trace).
    pub fn record(&self, rect: TileRect, light_points: usize, shininess: Arc<[f32]>) -> TileRecord {
        let with_shapes = self.shapes_allowed();
        match lock(&self.spares).pop() {
            Some(spare) => spare.reused(rect, light_points, with_shapes, shininess),
            None => TileRecord::new(rect, light_points, with_shapes, shininess),
        }
    }

    /// Gives a record no longer needed to the tiles still to come.
    pub fn recycle(&self, record: TileRecord) {
        lock(&self.spares).push(record);
    }

    /// Accounts a finished tile's record.
    pub fn add(&self, record: &TileRecord) {
        let bytes = record.bytes();
        if self.used.fetch_add(bytes, Ordering::Relaxed) + bytes > self.cap {
            self.shapes.store(false, Ordering::Relaxed);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::push_visibility_bits;

    #[test]
    fn visibility_bits_are_one_per_point_not_zero() {
        for count in [0usize, 1, 3, 4, 7, 63, 64, 65, 130, 257] {
            // Visible, hidden, −0 (hidden), NaN (visible, as `!=` has it)
            // and fractions, in a pattern that is not periodic in 4 or 64.
            let vis: Vec<f32> = (0..count)
                .map(|j| match (j * 7 + j / 5) % 6 {
                    0 => 0.0,
                    1 => -0.0,
                    2 => f32::NAN,
                    3 => 0.25,
                    _ => 1.0,
                })
                .collect();
            let mut want = vec![0u64; count.div_ceil(64)];
            for (j, &v) in vis.iter().enumerate() {
                want[j / 64] |= ((v != 0.0) as u64) << (j % 64);
            }
            // Padded to a multiple of 8 with leftovers of other points.
            let mut padded = vis.clone();
            padded.resize(count.next_multiple_of(8), 1.0);
            let mut got = vec![42];
            push_visibility_bits(&padded, count, &mut got);
            assert_eq!(got[0], 42, "appends");
            assert_eq!(&got[1..], &want[..], "{count} points");
        }
    }
}
