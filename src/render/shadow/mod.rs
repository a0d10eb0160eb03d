//! Shadow rays: which of a hit point's light points are visible.
//!
//! All shadow rays of one hit point share their origin, so they are handled
//! together, in f32, in coordinates relative to the hit point: that keeps
//! them precise for a room far from the world origin, and lets the compiler
//! vectorize the per-ray loops (structure of arrays, no branches).
//!
//! A ray from hit point p to light point y is blocked by an object met at
//! t ∈ (0, 1 − 10⁻⁴) on p + t (y − p) (see `RAY_END`). A light point
//! behind the surface (N·(y − p) ≤ 0) counts as blocked by the surface
//! itself. The surface's own object is otherwise left out: every primitive
//! is convex or flat, so a ray leaving it on the outer side can never meet
//! it again — exact, with no epsilon. Hit from inside (the normal was
//! flipped), the object is kept and only its exit point counts.
//!
//! Work is skipped where the answer is known (when `settings.skip`):
//! - objects whose bounds miss the pyramid spanned by p and the light
//!   rectangle can block nothing; planes with the whole light on p's side
//!   neither. With no candidate left, every facing point is visible. A
//!   hit point first narrows the objects to those of its small cube of
//!   space (`cells.rs`). Hit points whose few rays wait in lanes
//!   (`hit_lanes.rs`) are culled as a batch: an object is left out if it
//!   is clear of every ray of the batch (`batch_reach.rs`).
//! - if one convex candidate, lying wholly between p and the light's plane,
//!   blocks the rays to all four light corners, it blocks every ray to the
//!   light (the directions that meet a convex body form a convex cone).
//! - from [`PACKET_THRESHOLD`](super::scene::PACKET_THRESHOLD) objects on,
//!   the rays walk a BVH built in the light's frame as packets of 64
//!   (`light_frame.rs`, `ray_packet.rs`): a box is opened only with the
//!   rays whose light points lie in its footprint, grown by a margin far
//!   beyond the f32 tests' rounding, and a ray stops at its first blocker.
//!
//! All only decide what is also what tracing would find, so the image is
//! the same with skipping on or off.

mod batch_reach;
mod buffers;
mod cells;
mod hit_lanes;
pub(crate) mod light_frame;
mod occluder;
mod packet;
mod pyramid;
pub(crate) mod ray_packet;
mod visibility;

pub use buffers::ShadowBuffers;
pub(crate) use cells::OccluderCells;
pub(crate) use hit_lanes::{HitLanes, LANE_RAYS, lanes_fit};
pub use light_frame::OccluderBvh;
pub(crate) use packet::live_rays;
pub use visibility::ShadowQuery;
pub(crate) use visibility::{possible_occluders, visibility, visibility_inline};

/// Shadow rays end at this fraction of the way to their light point: a
/// surface the light lies in (a light flush with a ceiling) must not block
/// it, and in f32 the light point's side of such a surface is a coin toss
/// unless the geometry is axis-aligned. Occluders closer to the light than
/// 1e-4 of the ray's length are not seen (a relative margin, so it holds at
/// every scale; pbrt uses the same shadow epsilon).
pub(crate) const RAY_END: f32 = 1.0 - 1e-4;
