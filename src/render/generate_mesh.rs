//! Generated meshes for scale: a torus with a gentle low-frequency bump
//! (5 waves around, 3 across), tessellated as finely as asked. Every
//! tessellation has the same silhouette, so render times at different
//! triangle counts compare the meshes, not the images. Written as plain
//! OBJ (never committed: a million triangles are 38 MB).

use std::io::Write;
use std::path::Path;

use super::error::ImageError;
use super::output::write_atomic;

/// Major and minor radius: 2.8 wide and 0.8 (±5 %) thick, lying in the
/// xz plane around the origin.
const MAJOR: f64 = 1.0;
const MINOR: f64 = 0.4;
const BUMP: f64 = 0.05;

/// Segments around the ring and across the tube for about `triangles`
/// triangles (twice as many around as across; at least 3 × 3).
pub fn torus_segments(triangles: usize) -> (usize, usize) {
    let across = ((triangles as f64 / 4.0).sqrt().round() as usize).max(3);
    let around = (triangles / (2 * across)).max(3);
    (around, across)
}

/// Writes the torus of about `triangles` triangles as OBJ; returns the
/// exact count (2 · around · across). The write is atomic, as an image's
/// ([`write_atomic`]): a failed or interrupted one leaves no file and an
/// existing file untouched.
pub fn write_torus_obj(path: &Path, triangles: usize) -> Result<usize, ImageError> {
    let (nu, nv) = torus_segments(triangles);
    write_atomic(path, |out| {
        write_torus(out, nu, nv).map_err(|e| e.to_string())
    })?;
    Ok(2 * nu * nv)
}

/// The OBJ text of the torus of `nu` segments around and `nv` across.
fn write_torus(out: &mut impl Write, nu: usize, nv: usize) -> std::io::Result<()> {
    writeln!(
        out,
        "# penumbra generate torus: {} triangles ({nu} around × {nv} across)",
        2 * nu * nv
    )?;
    for i in 0..nu {
        let u = std::f64::consts::TAU * i as f64 / nu as f64;
        for j in 0..nv {
            let v = std::f64::consts::TAU * j as f64 / nv as f64;
            let r = MINOR * (1.0 + BUMP * (5.0 * u).sin() * (3.0 * v).sin());
            let ring = MAJOR + r * v.cos();
            writeln!(
                out,
                "v {:.6} {:.6} {:.6}",
                ring * u.cos(),
                r * v.sin(),
                ring * u.sin()
            )?;
        }
    }
    let at = |i: usize, j: usize| (i % nu) * nv + (j % nv) + 1;
    for i in 0..nu {
        for j in 0..nv {
            let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
            writeln!(out, "f {a} {b} {c}\nf {a} {c} {d}")?;
        }
    }
    Ok(())
}

/// The height of the torus's lowest point above its centre plane.
pub const TORUS_HALF_HEIGHT: f64 = MINOR * (1.0 + BUMP);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn segment_counts_meet_the_asked_triangles() {
        for n in [10_000, 100_000, 1_000_000, 2_000_000] {
            let (u, v) = torus_segments(n);
            let got = 2 * u * v;
            assert!((got as f64 / n as f64 - 1.0).abs() < 0.01, "{n}: {got}");
        }
    }

    #[test]
    fn the_written_torus_reads_back_closed() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.obj");
        let n = write_torus_obj(&path, 2_000).unwrap();
        let raw = crate::render::mesh::read_obj(&std::fs::read(&path).unwrap()).unwrap();
        assert_eq!(raw.faces.len(), n);
        // Closed: every edge is shared by exactly two faces.
        let mut edges = std::collections::HashMap::new();
        for f in &raw.faces {
            for k in 0..3 {
                let (a, b) = (f[k], f[(k + 1) % 3]);
                *edges.entry((a.min(b), a.max(b))).or_insert(0) += 1;
            }
        }
        assert!(edges.values().all(|&c| c == 2));
        let top = raw.positions.iter().map(|p| p.y).fold(f64::MIN, f64::max);
        assert!(top <= TORUS_HALF_HEIGHT && top > MINOR, "{top}");
    }
}
