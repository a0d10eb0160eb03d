//! Low-discrepancy shadow-ray points: a 2-D Owen-scrambled Sobol' sequence
//! (Burley 2020, "Practical Hash-based Owen Scrambling") and a
//! Cranley–Patterson-shifted grid.

/// Generator matrix columns of Sobol' dimension 1 (Joe–Kuo: primitive
/// polynomial x + 1, m₁ = 1), as 32-bit direction numbers v_k:
/// v₁ = 2³¹, v_k = v_{k−1} ⊕ (v_{k−1} ≫ 1) (the Pascal matrix mod 2).
const DIM1: [u32; 32] = {
    let mut v = [0u32; 32];
    v[0] = 1 << 31;
    let mut k = 1;
    while k < 32 {
        v[k] = v[k - 1] ^ (v[k - 1] >> 1);
        k += 1;
    }
    v
};

/// Dimension 1 of the index's bytes: entry `b` of table `k` is the xor of
/// the direction numbers of the bits set in byte `b` at bits 8k..8k + 8.
const DIM1_BYTES: [[u32; 256]; 4] = {
    let mut t = [[0u32; 256]; 4];
    let mut k = 0;
    while k < 4 {
        let mut b = 0;
        while b < 256 {
            let mut y = 0u32;
            let mut j = 0;
            while j < 8 {
                if b & (1 << j) != 0 {
                    y ^= DIM1[8 * k + j];
                }
                j += 1;
            }
            t[k][b] = y;
            b += 1;
        }
        k += 1;
    }
    t
};

/// Unscrambled Sobol' point `index` in dimensions 0 (van der Corput: the
/// bit-reversed index) and 1, as 32-bit fixed-point fractions. Dimension 1
/// is the xor of the direction numbers of the index's set bits, a byte at
/// a time (a branch per bit of a scrambled index, as random as its bits,
/// was mispredicted half the time).
#[inline]
fn sobol_u32(index: u32) -> (u32, u32) {
    let x = index.reverse_bits();
    let [b0, b1, b2, b3] = index.to_le_bytes();
    let y = DIM1_BYTES[0][b0 as usize]
        ^ DIM1_BYTES[1][b1 as usize]
        ^ DIM1_BYTES[2][b2 as usize]
        ^ DIM1_BYTES[3][b3 as usize];
    (x, y)
}

/// Laine & Karras (2011) permutation as improved by Burley (2020): every
/// output bit is its input bit xor a function of the *lower* bits only, so
/// on bit-reversed values it is a nested (Owen) scramble.
#[inline]
fn laine_karras_permutation(mut x: u32, seed: u32) -> u32 {
    x = x.wrapping_add(seed);
    x ^= x.wrapping_mul(0x6c50_b47c);
    x ^= x.wrapping_mul(0xb82f_1e52);
    x ^= x.wrapping_mul(0xc7af_e638);
    x ^= x.wrapping_mul(0x8d22_f6e6);
    x
}

/// Owen scramble of a 32-bit fraction: each bit flipped by a hash of the
/// bits above it.
#[inline]
fn nested_uniform_scramble(x: u32, seed: u32) -> u32 {
    laine_karras_permutation(x.reverse_bits(), seed).reverse_bits()
}

/// A 32-bit integer hash (Wellons' lowbias32) to derive independent
/// per-dimension seeds from one seed.
#[inline]
fn hash(mut x: u32) -> u32 {
    x ^= x >> 16;
    x = x.wrapping_mul(0x7feb_352d);
    x ^= x >> 15;
    x = x.wrapping_mul(0x846c_a68b);
    x ^ (x >> 16)
}

/// 32-bit fraction → f32 in [0, 1): the top 24 bits, so rounding never
/// reaches 1.0.
#[inline]
fn to_unit(x: u32) -> f32 {
    (x >> 8) as f32 * (1.0 / (1u32 << 24) as f32)
}

/// Point `index` of the Owen-scrambled, shuffled 2-D Sobol' sequence for a
/// given seed (use one seed per pixel, e.g. a hash of pixel and depth), in
/// [0,1)². The index is first Owen-scrambled (Burley's shuffling, which
/// decorrelates pixels that use the same indices), then each dimension is
/// Owen-scrambled with its own seed.
///
/// Guarantee: for every m, the points of indices `0..2^m` form a (0, m, 2)
/// net in base 2 — every elementary box of area 2^−m, in particular every
/// cell of a 2^k × 2^k grid when m = 2k, holds exactly one point — because
/// the shuffle maps `0..2^m` onto an aligned block of 2^m consecutive
/// Sobol' indices and Owen scrambling preserves nets.
pub fn sobol_2d(index: u32, seed: u32) -> (f32, f32) {
    let shuffled = nested_uniform_scramble(index, hash(seed));
    let (x, y) = sobol_u32(shuffled);
    let sx = nested_uniform_scramble(x, hash(seed ^ 0x68bc_21eb));
    let sy = nested_uniform_scramble(y, hash(seed ^ 0x02e5_be93));
    (to_unit(sx), to_unit(sy))
}

/// The first `count` unscrambled Sobol' points with their bits reversed:
/// the per-pattern half of [`scrambled_point`], computed once per render.
pub fn sobol_table(count: usize) -> Vec<(u32, u32)> {
    (0..count as u32)
        .map(|i| {
            let (x, y) = sobol_u32(i);
            (x.reverse_bits(), y.reverse_bits())
        })
        .collect()
}

/// A [`sobol_table`] entry, Owen-scrambled in each dimension with its own
/// seed, in [0,1)². Points `0..2^m` of a table scrambled with one pair of
/// seeds form a (0, m, 2) net, as Owen scrambling preserves nets. Cheaper
/// than [`sobol_2d`] (no index shuffle, no per-point Sobol' evaluation),
/// which is what a renderer that takes every index of a prefix needs.
#[inline]
pub fn scrambled_point(entry: (u32, u32), seed_x: u32, seed_y: u32) -> (f32, f32) {
    (
        to_unit(laine_karras_permutation(entry.0, seed_x).reverse_bits()),
        to_unit(laine_karras_permutation(entry.1, seed_y).reverse_bits()),
    )
}

/// Point (i, j) of an n×n grid of cell centres shifted toroidally by
/// (shift_u, shift_v) ∈ [0,1)² (a Cranley–Patterson rotation; draw one
/// shift per pixel): ((i + ½)/n + shift_u mod 1, (j + ½)/n + shift_v mod 1),
/// in [0,1)². Every cell of the n×n grid still holds exactly one point, and
/// the per-pixel shift turns the grid's bands into unbiased noise.
pub fn rotated_grid(n: u32, i: u32, j: u32, shift_u: f32, shift_v: f32) -> (f32, f32) {
    let inv = 1.0 / n.max(1) as f32;
    let wrap = |x: f32| {
        let f = x - x.floor();
        // f32 rounding can turn 1 − ε into 1.0.
        if f >= 1.0 { 0.0 } else { f }
    };
    (
        wrap((i as f32 + 0.5) * inv + shift_u),
        wrap((j as f32 + 0.5) * inv + shift_v),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unscrambled_matches_known_sobol_prefix() {
        // Dimension 1 of Sobol' in natural (not Gray-code) order.
        let want = [0.0, 0.5, 0.75, 0.25, 0.625, 0.125, 0.375, 0.875];
        for (i, w) in want.iter().enumerate() {
            let (x, y) = sobol_u32(i as u32);
            assert_eq!(to_unit(y), *w, "index {i}");
            assert_eq!(x, (i as u32).reverse_bits());
        }
    }

    #[test]
    fn dimension_one_by_bytes_is_the_xor_of_each_set_bit_s_direction() {
        let by_bits = |i: u32| {
            (0..32)
                .filter(|k| i & (1 << k) != 0)
                .fold(0u32, |y, k| y ^ DIM1[k])
        };
        let mut i = 0x9e37_79b9u32;
        for k in (0..4096u32).chain([u32::MAX, 1 << 31, 0x00ff_ff00]) {
            // Every index below 4096, then scrambled-looking ones.
            i = i.wrapping_mul(0x2c1b_3c6d).wrapping_add(0x297a_2d39);
            for index in [k, i] {
                assert_eq!(sobol_u32(index).1, by_bits(index), "index {index:#x}");
            }
        }
    }

    #[test]
    fn points_in_unit_square() {
        for seed in [0, 1, 0xdead_beef, u32::MAX] {
            for i in (0..100_000u32).chain([u32::MAX - 1, u32::MAX]) {
                let (x, y) = sobol_2d(i, seed);
                assert!((0.0..1.0).contains(&x) && (0.0..1.0).contains(&y));
            }
        }
        for n in 1..20 {
            for i in 0..n {
                for (su, sv) in [(0.0, 0.0), (0.999_999_9, 0.5), (0.3, 0.999_999_94)] {
                    let (x, y) = rotated_grid(n, i, n - 1 - i, su, sv);
                    assert!((0.0..1.0).contains(&x) && (0.0..1.0).contains(&y));
                }
            }
        }
    }

    /// Each of the 2^k × 2^k cells holds exactly one of the first 4^k points.
    fn stratified(points: &[(f32, f32)], side: usize) -> bool {
        let mut seen = vec![false; side * side];
        for &(x, y) in points {
            let c = (y * side as f32) as usize * side + (x * side as f32) as usize;
            if seen[c] {
                return false;
            }
            seen[c] = true;
        }
        seen.iter().all(|&s| s)
    }

    #[test]
    fn power_of_two_prefixes_are_stratified() {
        for seed in [0u32, 7, 12345, 0x9e37_79b9, u32::MAX] {
            let pts: Vec<_> = (0..1u32 << 12).map(|i| sobol_2d(i, seed)).collect();
            for k in 0..=6 {
                let m = 1usize << (2 * k);
                assert!(stratified(&pts[..m], 1 << k), "seed {seed}, 4^{k}");
            }
            // (0, m, 2)-net: every elementary box 2^-a × 2^-(m-a) of the
            // first 2^m points holds exactly one, for odd m too.
            for m in 0..=12 {
                for wx in 0..=m {
                    let (cx, cy) = (1usize << wx, 1usize << (m - wx));
                    let mut seen = vec![false; 1 << m];
                    for &(x, y) in &pts[..1 << m] {
                        let c = (y * cy as f32) as usize * cx + (x * cx as f32) as usize;
                        assert!(!seen[c], "seed {seed}, 2^{m} points, box {cx}×{cy}");
                        seen[c] = true;
                    }
                }
            }
        }
    }

    #[test]
    fn shifted_grid_is_stratified() {
        for n in [1u32, 2, 3, 8, 13] {
            for (su, sv) in [(0.0, 0.0), (0.37, 0.91), (0.999, 0.001)] {
                let pts: Vec<_> = (0..n * n)
                    .map(|k| rotated_grid(n, k % n, k / n, su, sv))
                    .collect();
                assert!(stratified(&pts, n as usize), "n {n}, shift {su} {sv}");
            }
        }
    }

    #[test]
    fn seeds_decorrelate_and_are_deterministic() {
        let a: Vec<_> = (0..64).map(|i| sobol_2d(i, 1)).collect();
        let b: Vec<_> = (0..64).map(|i| sobol_2d(i, 2)).collect();
        let a2: Vec<_> = (0..64).map(|i| sobol_2d(i, 1)).collect();
        assert_eq!(a, a2);
        let same = a.iter().zip(&b).filter(|(p, q)| p == q).count();
        assert_eq!(same, 0);
        // Over many seeds, point 0 is spread uniformly (mean ≈ ½).
        let n = 10_000;
        let (mx, my) = (0..n).fold((0.0, 0.0), |(mx, my), s| {
            let (x, y) = sobol_2d(0, s);
            (mx + x as f64 / n as f64, my + y as f64 / n as f64)
        });
        assert!(
            (mx - 0.5).abs() < 0.02 && (my - 0.5).abs() < 0.02,
            "{mx} {my}"
        );
    }

    #[test]
    fn scrambled_table_points_are_nets() {
        let table = sobol_table(256);
        for seed in [1u32, 77, 0xdead_beef] {
            let pts: Vec<(f32, f32)> = table
                .iter()
                .map(|&e| scrambled_point(e, hash(seed), hash(seed ^ 1)))
                .collect();
            // Each cell of the 16×16 grid holds exactly one of the 256 points.
            let mut cells = [0u8; 256];
            for &(x, y) in &pts {
                assert!((0.0..1.0).contains(&x) && (0.0..1.0).contains(&y));
                cells[(y * 16.0) as usize * 16 + (x * 16.0) as usize] += 1;
            }
            assert!(cells.iter().all(|&c| c == 1), "seed {seed}");
        }
        let a = scrambled_point(table[3], 1, 2);
        let b = scrambled_point(table[3], 3, 4);
        assert_ne!(a, b);
    }
}
