//! Generated scenes for benchmarks and tests: the seed room (walls, light,
//! camera, materials) with its boxes and sphere replaced by N random
//! spheres, deterministic from a seed.
//!
//! The spheres' radius shrinks as N^(-1/3) so that together they fill a
//! constant fraction of the room whatever N is. Their cross-sections add up
//! to more as N grows (N·r² ∝ N^(1/3)): a ray's free path between spheres
//! shrinks as N^(-1/3), so larger N means more covered surface, darker
//! shadows and shadow rays that pass more spheres on their way to the light.

use super::rng::Rng;
use super::scene::SEED_ROOM_JSON;
use super::scene_file::{ObjectDesc, SceneDesc, SphereDesc};

/// The box spheres are placed in: the seed room's side walls (x = ±5), floor
/// (y = 0) and back wall (z = 5); the top stops short of the light
/// (y = 7.99) and the open front is closed at z = -5, well before the
/// camera (z = -14).
pub const ROOM_MIN: [f64; 3] = [-5.0, 0.0, -5.0];
pub const ROOM_MAX: [f64; 3] = [5.0, 7.5, 5.0];

/// Fraction of [`ROOM_MIN`]..[`ROOM_MAX`] the spheres' volumes add up to
/// (ignoring overlaps).
pub const VOLUME_FRACTION: f64 = 0.05;

/// Fraction of the floor the spheres of [`Layout::Floor`] cover (ignoring
/// overlaps).
pub const FLOOR_COVERAGE: f64 = 0.3;

/// The seed room's objects the spheres join: its planes and rects.
pub const ROOM_OBJECTS: usize = 5;

/// Most spheres a generated room holds: the format's object limit less the
/// room's own objects (more would be refused as a scene of too many
/// objects, which no option of the bench's names).
pub const MAX_SPHERES: usize = super::scene_file::limits::MAX_OBJECTS - ROOM_OBJECTS;

/// Where the generated spheres go.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Layout {
    /// Anywhere in the room, filling [`VOLUME_FRACTION`] of it: the more
    /// spheres, the denser the fog between the floor and the light.
    #[default]
    Volume,
    /// One layer on the floor, covering [`FLOOR_COVERAGE`] of it: what a
    /// shadow ray crosses stays the same whatever N is.
    Floor,
}

/// Materials the spheres draw from, by name in the seed room; the mirror
/// keeps some reflected rays in the workload.
const MATERIALS: [&str; 6] = ["white", "red", "green", "steel", "sand", "mirror"];

/// Coordinates are rounded to millionths: short decimals survive a JSON
/// round trip exactly (serde_json's default parser can be off by an ulp on
/// 17-digit numbers), so a saved generated scene is the scene measured.
const PER_UNIT: f64 = 1e6;
const STEP: f64 = 1.0 / PER_UNIT;

/// The double nearest to a multiple of a millionth (one correctly rounded
/// division of an integer, so it prints as a short decimal).
fn round(x: f64) -> f64 {
    (x * PER_UNIT).round() / PER_UNIT
}

/// Radius of each of `n` spheres filling [`VOLUME_FRACTION`] of the room.
pub fn sphere_radius(n: usize) -> f64 {
    let volume: f64 = (0..3).map(|i| ROOM_MAX[i] - ROOM_MIN[i]).product();
    round((3.0 * VOLUME_FRACTION * volume / (4.0 * std::f64::consts::PI * n.max(1) as f64)).cbrt())
}

/// Radius of each of `n` spheres covering [`FLOOR_COVERAGE`] of the floor.
pub fn floor_sphere_radius(n: usize) -> f64 {
    let area = (ROOM_MAX[0] - ROOM_MIN[0]) * (ROOM_MAX[2] - ROOM_MIN[2]);
    round((FLOOR_COVERAGE * area / (std::f64::consts::PI * n.max(1) as f64)).sqrt())
}

/// The spheres' radius in a layout.
pub fn radius(layout: Layout, n: usize) -> f64 {
    match layout {
        Layout::Volume => sphere_radius(n),
        Layout::Floor => floor_sphere_radius(n),
    }
}

/// The seed room with `n` random spheres instead of its boxes and sphere,
/// anywhere in the room ([`Layout::Volume`]).
pub fn spheres_in_room(n: usize, seed: u64) -> SceneDesc {
    generate(n, seed, Layout::Volume)
}

/// The seed room with `n` random spheres laid out as asked. The same `(n,
/// seed, layout)` always gives the same scene; every sphere lies strictly
/// inside [`ROOM_MIN`]..[`ROOM_MAX`], touching no wall (nor the floor).
pub fn generate(n: usize, seed: u64, layout: Layout) -> SceneDesc {
    let mut desc = SceneDesc::from_json(SEED_ROOM_JSON).expect("the built-in seed room is valid");
    desc.objects
        .retain(|o| matches!(o, ObjectDesc::Plane(_) | ObjectDesc::Rect(_)));
    let radius = radius(layout, n);
    // Clearance for the rounding of the centres, so that no sphere touches
    // a wall.
    let clearance = radius + 2.0 * STEP;
    let (lo, hi) = match layout {
        Layout::Volume => (ROOM_MIN, ROOM_MAX),
        // Resting just above the floor.
        Layout::Floor => {
            let y = ROOM_MIN[1] + clearance;
            (
                [ROOM_MIN[0], y - clearance, ROOM_MIN[2]],
                [ROOM_MAX[0], y + clearance, ROOM_MAX[2]],
            )
        }
    };
    let mut rng = Rng::new(seed);
    let mut uniform =
        |lo: f64, hi: f64| lo + (hi - lo) * (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64;
    desc.objects.reserve(n);
    for _ in 0..n {
        let center: [f64; 3] =
            std::array::from_fn(|i| round(uniform(lo[i] + clearance, hi[i] - clearance)));
        let material =
            MATERIALS[(uniform(0.0, MATERIALS.len() as f64) as usize).min(MATERIALS.len() - 1)];
        desc.objects.push(ObjectDesc::Sphere(SphereDesc {
            center,
            radius,
            material: material.to_string(),
        }));
    }
    desc
}
