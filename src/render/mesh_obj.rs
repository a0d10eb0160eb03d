//! Plain Wavefront OBJ read fast: `v` lines (a w or a vertex colour after
//! the position is read past), `vn` and `f` lines (with any of the index
//! forms `v`, `v/t`, `v//n`, `v/t/n`, negative indices included), on all
//! threads, streaming into the mesh's arrays.
//!
//! `tobj` keeps a hash map entry per vertex and a 72-byte record per face
//! before the mesh comes out (about 0.9 s and 200 MB for a million
//! triangles); this reader needs a tenth of that. It gives up (`None`) on
//! anything outside that subset or wrong (a malformed number, an index
//! out of range, ...; line continuations are joined before it): `read_obj` then names the line
//! that is wrong, or reads the file through `tobj`. The triangles are the same either way (a test compares them;
//! only the numbering of vertices differs: `tobj` numbers them in order of
//! first use).

use glam::DVec3;
use rayon::prelude::*;

use super::mesh::{NO_NORMAL, RawMesh};

/// Bytes per parallel chunk (cut at line ends).
const CHUNK: usize = 1 << 20;

/// What one chunk holds.
#[derive(Default)]
struct Chunk {
    positions: Vec<DVec3>,
    normals: Vec<DVec3>,
    faces: Vec<[u32; 3]>,
    /// Each face's normal indices, [`NO_NORMAL`] where a corner has none.
    face_normals: Vec<[u32; 3]>,
    /// Faces with a normal index at every corner.
    faces_with_normals: usize,
}

/// Counts of one chunk's `v`, `vt` and `vn` lines.
#[derive(Default, Clone, Copy)]
struct Counts {
    v: u32,
    vt: u32,
    vn: u32,
}

/// The mesh, or `None` if the file is not plain OBJ (see the module).
pub fn read_plain_obj(bytes: &[u8]) -> Option<RawMesh> {
    if bytes.contains(&b'\\') || bytes.contains(&0) {
        return None;
    }
    // Chunks end at line ends.
    let mut cuts = vec![0];
    while *cuts.last().unwrap() < bytes.len() {
        let from = cuts.last().unwrap() + CHUNK;
        if from >= bytes.len() {
            cuts.push(bytes.len());
            break;
        }
        let end = bytes[from..]
            .iter()
            .position(|&b| b == b'\n')
            .map_or(bytes.len(), |p| from + p + 1);
        cuts.push(end);
    }
    let ranges: Vec<&[u8]> = cuts.windows(2).map(|w| &bytes[w[0]..w[1]]).collect();
    // First pass: how many vertices each chunk holds, so that the second
    // knows how many come before it.
    let counts: Vec<Counts> = ranges.par_iter().map(|r| count(r)).collect();
    let mut before = Vec::with_capacity(counts.len());
    let mut total = Counts::default();
    for c in &counts {
        before.push(total);
        total.v = total.v.checked_add(c.v)?;
        total.vt = total.vt.checked_add(c.vt)?;
        total.vn = total.vn.checked_add(c.vn)?;
    }
    let chunks: Vec<Chunk> = ranges
        .par_iter()
        .zip(before.par_iter())
        .map(|(r, b)| parse(r, *b))
        .collect::<Option<Vec<Chunk>>>()?;
    let mut raw = RawMesh::default();
    let sum = |f: fn(&Chunk) -> usize| chunks.iter().map(f).sum::<usize>();
    raw.positions.reserve_exact(sum(|c| c.positions.len()));
    raw.faces.reserve_exact(sum(|c| c.faces.len()));
    let with_normals = sum(|c| c.faces_with_normals) > 0 && total.vn > 0;
    if with_normals {
        raw.normals.reserve_exact(sum(|c| c.normals.len()));
    }
    let mut face_normals = Vec::with_capacity(if with_normals {
        sum(|c| c.faces.len())
    } else {
        0
    });
    for c in chunks {
        raw.positions.extend_from_slice(&c.positions);
        raw.faces.extend_from_slice(&c.faces);
        if with_normals {
            raw.normals.extend_from_slice(&c.normals);
            face_normals.extend_from_slice(&c.face_normals);
        }
    }
    if with_normals {
        raw.face_normals = Some(face_normals);
    }
    Some(raw)
}

/// The first word of a line, and the rest.
#[inline]
fn key(line: &[u8]) -> (&[u8], &[u8]) {
    let line = line.trim_ascii_start();
    let end = line
        .iter()
        .position(|b| b.is_ascii_whitespace())
        .unwrap_or(line.len());
    (&line[..end], &line[end..])
}

fn count(bytes: &[u8]) -> Counts {
    let mut c = Counts::default();
    for line in bytes.split(|&b| b == b'\n') {
        match key(line).0 {
            b"v" => c.v += 1,
            b"vt" => c.vt += 1,
            b"vn" => c.vn += 1,
            _ => {}
        }
    }
    c
}

/// Three finite numbers and nothing more, or (`extra`) also those with a
/// w (4 numbers) or a colour (6) after them, which a mesh does not use.
#[inline]
fn three_numbers(rest: &[u8], extra: bool) -> Option<DVec3> {
    let mut words = rest
        .split(|b| b.is_ascii_whitespace())
        .filter(|w| !w.is_empty());
    let number = |w: &[u8]| -> Option<f64> {
        let x = match decimal(w) {
            Some(x) => x,
            None => std::str::from_utf8(w).ok()?.parse().ok()?,
        };
        x.is_finite().then_some(x)
    };
    let mut v = [0.0; 3];
    for x in &mut v {
        *x = number(words.next()?)?;
    }
    let mut more = 0;
    for w in words {
        number(w)?;
        more += 1;
    }
    let allowed: &[usize] = if extra { &[0, 1, 3] } else { &[0] };
    allowed.contains(&more).then_some(DVec3::from(v))
}

/// A plain decimal `[-]digits.digits` of at most 15 digits, read exactly
/// as `str::parse` reads it, and fast: the digits are an integer m < 2⁵³
/// and the divisor 10^k (k ≤ 15) is exact, so m / 10^k is one correctly
/// rounded division (Clinger's fast path). Anything else is left to
/// `str::parse` (`None`).
#[inline]
fn decimal(word: &[u8]) -> Option<f64> {
    const POW10: [f64; 16] = [
        1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15,
    ];
    let (neg, digits) = match word.first()? {
        b'-' => (true, &word[1..]),
        _ => (false, word),
    };
    let dot = digits.iter().position(|&b| b == b'.')?;
    let (int, frac) = (&digits[..dot], &digits[dot + 1..]);
    if int.is_empty() || frac.is_empty() || int.len() + frac.len() > 15 {
        return None;
    }
    let mut m: u64 = 0;
    for &d in int.iter().chain(frac) {
        if !d.is_ascii_digit() {
            return None;
        }
        m = m * 10 + (d - b'0') as u64;
    }
    let x = m as f64 / POW10[frac.len()];
    Some(if neg { -x } else { x })
}

/// A 1-based or negative (relative) index among `total` earlier items, as
/// a 0-based one.
#[inline]
fn index(word: &[u8], total: u32) -> Option<u32> {
    let (neg, digits) = match word.first()? {
        b'-' => (true, &word[1..]),
        _ => (false, word),
    };
    if digits.is_empty() || digits.len() > 10 {
        return None;
    }
    let mut n: u64 = 0;
    for &d in digits {
        if !d.is_ascii_digit() {
            return None;
        }
        n = n * 10 + (d - b'0') as u64;
    }
    if n == 0 || n > total as u64 {
        return None;
    }
    Some(if neg { total - n as u32 } else { n as u32 - 1 })
}

/// One chunk's lines; `before`: the counts of the chunks before it.
fn parse(bytes: &[u8], before: Counts) -> Option<Chunk> {
    let mut c = Chunk::default();
    let mut seen = before;
    let mut corner_v = Vec::with_capacity(8);
    let mut corner_n = Vec::with_capacity(8);
    for line in bytes.split(|&b| b == b'\n') {
        let (k, rest) = key(line);
        match k {
            b"v" => {
                c.positions.push(three_numbers(rest, true)?);
                seen.v += 1;
            }
            b"vn" => {
                c.normals.push(three_numbers(rest, false)?);
                seen.vn += 1;
            }
            b"vt" => seen.vt += 1,
            b"f" => {
                corner_v.clear();
                corner_n.clear();
                for w in rest
                    .split(|b| b.is_ascii_whitespace())
                    .filter(|w| !w.is_empty())
                {
                    let mut parts = w.split(|&b| b == b'/');
                    corner_v.push(index(parts.next()?, seen.v)?);
                    match parts.next() {
                        None => corner_n.push(None),
                        Some(t) => {
                            if !t.is_empty() {
                                index(t, seen.vt)?;
                            }
                            match parts.next() {
                                None | Some(b"") => corner_n.push(None),
                                Some(n) => corner_n.push(Some(index(n, seen.vn)?)),
                            }
                            if parts.next().is_some() {
                                return None;
                            }
                        }
                    }
                }
                if corner_v.len() < 3 {
                    return None;
                }
                // A fan from the first corner, as `tobj` triangulates.
                for j in 1..corner_v.len() - 1 {
                    c.faces.push([corner_v[0], corner_v[j], corner_v[j + 1]]);
                    match (corner_n[0], corner_n[j], corner_n[j + 1]) {
                        (Some(a), Some(b), Some(d)) => {
                            c.face_normals.push([a, b, d]);
                            c.faces_with_normals += 1;
                        }
                        _ => c.face_normals.push(NO_NORMAL),
                    }
                }
            }
            // Comments, names, groups, materials, smoothing groups, points
            // and lines carry nothing a mesh needs here.
            b"" | b"o" | b"g" | b"s" | b"usemtl" | b"mtllib" | b"l" | b"p" => {}
            k if k.starts_with(b"#") => {}
            _ => return None,
        }
    }
    Some(c)
}

#[cfg(test)]
mod tests {
    use super::decimal;

    /// The fast path reads every number it takes as `str::parse` does, bit
    /// for bit, and leaves the rest to it.
    #[test]
    fn decimals_read_as_str_parse_reads_them() {
        let mut state = 7u64;
        for _ in 0..200_000 {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let int = (state >> 40) % 100_000;
            let frac_digits = ((state >> 20) % 11) as usize;
            let frac = (state >> 8) % 10u64.pow(frac_digits as u32).max(1);
            let sign = if state & 1 == 0 { "" } else { "-" };
            let text = if frac_digits == 0 {
                format!("{sign}{int}.0")
            } else {
                format!("{sign}{int}.{frac:0frac_digits$}")
            };
            let fast = decimal(text.as_bytes()).expect(&text);
            let std: f64 = text.parse().unwrap();
            assert_eq!(fast.to_bits(), std.to_bits(), "{text}");
        }
        for text in [
            "1",
            ".5",
            "5.",
            "1e3",
            "+1.0",
            "1.0e2",
            "nan",
            "0x1.0",
            "1234567890.1234567",
        ] {
            assert_eq!(decimal(text.as_bytes()), None, "{text}");
        }
        assert_eq!(
            decimal(b"-0.000000").unwrap().to_bits(),
            (-0.0f64).to_bits()
        );
    }
}
