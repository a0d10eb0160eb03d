//! A light edit (its position or size) over recorded paths: the camera and
//! the objects stand, so each ray of a path meets what it met before —
//! unless the light now lies in its way. A path is traced again with the
//! tracer's own code, each hit's object and distance taken from the record
//! instead of intersecting the scene, as long as the new light is not
//! nearer on that ray; from the first ray it is (or one the record does
//! not have, or one that met the old light), the rest of the path is
//! intersected as a fresh render does. Its shadow rays and light factors
//! are all new, so the image is a fresh render's, bit for bit.
//!
//! Why a recorded hit is the fresh one: the scene tests the light first
//! and then keeps objects strictly nearer than it (`Scene::closest_hit`).
//! The recorded object was the nearest of all (it was nearer than the old
//! light, or there was none), so with the new light farther, or missed,
//! it is found again at the same distance.

use std::sync::Mutex;

use super::record::{TileRecord, TileRecorder};
use crate::render::geometry::{Parallelogram, Ray};
use crate::render::scene::HitTarget;
use crate::render::shading::LightTerms;
use crate::render::shadow::ShadowBuffers;
use crate::render::tracer::{HitRecord, PathEnd, PathSink};

/// Follows the recorded paths of one tile (`old`) under a new light while
/// recording them again into `recorder`.
pub struct Relighter<'a> {
    recorder: TileRecorder<'a>,
    old: &'a TileRecord,
    light: &'a Parallelogram,
    /// Whether reflected rays start where they did: the offset of their
    /// origins scales with the scene's size, which the light is part of.
    reflections: bool,
    /// The path being traced, and whether it has left its record.
    path: usize,
    diverged: bool,
}

impl<'a> Relighter<'a> {
    pub fn new(
        recorder: TileRecorder<'a>,
        old: &'a TileRecord,
        light: &'a Parallelogram,
        reflections: bool,
    ) -> Relighter<'a> {
        Relighter {
            recorder,
            old,
            light,
            reflections,
            path: 0,
            diverged: false,
        }
    }

    /// Whether the new light is hit on `ray` no farther than `t` (which
    /// the light would win: objects must be strictly nearer).
    #[inline]
    fn light_within(&self, ray: &Ray, t: f64) -> bool {
        self.light.intersect(ray, t.next_up()).is_some()
    }
}

impl PathSink for Relighter<'_> {
    const RECORD: bool = true;
    // Its camera hits are the recorded ones, unless a path diverged.
    const FINDS_CAMERA_HITS: bool = false;

    #[inline(always)]
    fn nearest(
        &mut self,
        depth: u32,
        ray: &Ray,
        find: impl FnOnce() -> Option<(HitTarget, f64)>,
    ) -> Option<(HitTarget, f64)> {
        if self.diverged
            || (depth > 1 && !self.reflections)
            || self.path + 1 >= self.old.starts.len()
        {
            self.diverged = true;
            return find();
        }
        let hits = self.old.path_hits(self.path);
        let k = hits.start + depth as usize - 1;
        if k < hits.end {
            let t = self.old.distances[k];
            if !self.light_within(ray, t) {
                return Some((HitTarget::Object(self.old.objects[k]), t));
            }
        } else if k == hits.end
            && self.old.ends[self.path] == PathEnd::Background
            && !self.light_within(ray, f64::INFINITY)
        {
            return None;
        }
        self.diverged = true;
        find()
    }

    #[inline(always)]
    fn hit(&mut self, hit: HitRecord, buf: &ShadowBuffers, count: usize) -> usize {
        self.recorder.hit(hit, buf, count)
    }

    #[inline(always)]
    fn set_factors(&mut self, index: usize, factors: LightTerms) {
        self.recorder.set_factors(index, factors);
    }

    #[inline(always)]
    fn set_visible(&mut self, index: usize, bits: u64) {
        self.recorder.set_visible(index, bits);
    }

    #[inline]
    fn end(&mut self, end: PathEnd) {
        self.recorder.end(end);
        self.path += 1;
        self.diverged = false;
    }
}

/// What a light edit's final pass follows: the last frame's records, tile
/// by tile in the order of `tiles_of` (each taken, and so freed, when its
/// tile is traced).
pub struct Previous {
    pub tiles: Vec<Mutex<Option<TileRecord>>>,
    /// See [`Relighter`].
    pub reflections: bool,
}
