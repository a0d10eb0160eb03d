//! Fuzz target, structure-aware: valid scenes with extreme numbers.
//!
//! Byte-level mutation of JSON text mostly yields text that does not parse,
//! so this target keeps the structure of a real scene and lets the input
//! rewrite its numbers: keep, scale by a power of ten, negate, zero, nudge
//! by a few ulps, or replace by a value from a table of awkward ones. A
//! scene the validator accepts must render (8×8, capped shadow rays and
//! depth) to finite pixels; one it refuses must be refused without a panic.
//!
//! Run (stable toolchain):
//! `RUSTC_BOOTSTRAP=1 cargo fuzz run -s none --no-trace-compares render_numbers -- -max_len=512 -max_total_time=600`

#![no_main]

mod common;

use libfuzzer_sys::fuzz_target;
use penumbra::render::SceneDesc;
use serde_json::Value;

const BASES: [&str; 6] = [
    include_str!("../../scenes/seed-room.json"),
    include_str!("../../scenes/stress/light-in-ceiling.json"),
    include_str!("../../scenes/stress/camera-in-light-plane.json"),
    include_str!("../../scenes/stress/light-edge.json"),
    include_str!("../../scenes/stress/parallel-mirrors.json"),
    include_str!("../../scenes/stress/shared-face.json"),
];

const AWKWARD: [f64; 16] = [
    0.0,
    -0.0,
    1.0,
    0.5,
    1e-9,
    1e9,
    -1e9,
    1e-300,
    5e-324,
    1e6,
    1e-6,
    4096.0,
    16.0,
    16384.0,
    179.999_999,
    1e-3,
];

fn mutate(v: &mut Value, bytes: &mut impl Iterator<Item = u8>) {
    match v {
        Value::Number(n) => {
            let Some(op) = bytes.next() else { return };
            let x = n.as_f64().unwrap_or(0.0);
            let arg = bytes.next().unwrap_or(0);
            let y = match op % 8 {
                0..=2 => return,
                3 => x * 10f64.powi((arg as i8 / 8) as i32),
                4 => -x,
                5 => 0.0,
                6 => x * (1.0 + f64::EPSILON * (arg as f64 - 128.0)),
                _ => AWKWARD[arg as usize % AWKWARD.len()],
            };
            // Integers stay integers where they can (sizes, counts, seed).
            *v = if y.fract() == 0.0 && y.abs() < 1e15 && n.is_u64() && y >= 0.0 {
                Value::from(y as u64)
            } else {
                serde_json::Number::from_f64(y).map_or(Value::Null, Value::Number)
            };
        }
        Value::Array(a) => a.iter_mut().for_each(|x| mutate(x, bytes)),
        Value::Object(o) => o.values_mut().for_each(|x| mutate(x, bytes)),
        _ => {}
    }
}

fuzz_target!(|data: &[u8]| {
    let Some((&which, rest)) = data.split_first() else {
        return;
    };
    // The bases are parsed once: parsing them on every run took a tenth of
    // the target's time.
    static PARSED: std::sync::OnceLock<Vec<Value>> = std::sync::OnceLock::new();
    let parsed = PARSED.get_or_init(|| {
        BASES
            .iter()
            .map(|b| serde_json::from_str(b).unwrap())
            .collect()
    });
    let mut v = parsed[which as usize % parsed.len()].clone();
    mutate(&mut v, &mut rest.iter().copied());
    let Ok(desc) = SceneDesc::from_json(&v.to_string()) else {
        return;
    };
    if let Some((i, p)) = common::first_non_finite_pixel(desc.clone()) {
        panic!("non-finite pixel {i}: {p:?}\n{}", desc.to_json());
    }
});
