//! Packing report: laminae relative density (Ivannikov et al. 2022 eq. 48), a minimal VTU writer
//! for spheres, and a minimal PNG line plot (main has no shared plot/VTU facility yet; these live
//! here until it does).

use crate::error::{Error, IoError};
use nalgebra::Vector3;
use std::io::Write;
use std::path::Path;

/// Volume [m³] of a sphere of radius `r` centred at `c` that lies between the planes `a ≤ s ≤ b`
/// (coordinates along the same axis): `∫ π(r² − (s−c)²) ds` over the clipped interval.
pub fn slab_volume(c: f64, r: f64, a: f64, b: f64) -> f64 {
    let lo = (a - c).max(-r);
    let hi = (b - c).min(r);
    if hi <= lo {
        return 0.0;
    }
    let f = |z: f64| r * r * z - z * z * z / 3.0;
    std::f64::consts::PI * (f(hi) - f(lo))
}

/// Laminae of one axis: centres [m] and relative densities ρ_rel,s = V_particles,s / V_lamina,s (eq. 48).
#[derive(Debug, Clone, PartialEq)]
pub struct Laminae {
    pub axis: usize,
    pub centres: Vec<f64>,
    pub density: Vec<f64>,
    /// Whether the lamina lies at least `interior_margin` from both walls.
    pub interior: Vec<bool>,
}

/// Cuts the box `[lo, hi]` along `axis` into laminae of width ≈ `width` (the extent divided into
/// a whole number of equal laminae) and computes eq. 48 for each.
pub fn laminae(pos: &[Vector3<f64>], rad: &[f64], lo: &Vector3<f64>, hi: &Vector3<f64>, axis: usize, width: f64, interior_margin: f64) -> Laminae {
    let ext = hi[axis] - lo[axis];
    let n = ((ext / width).round() as usize).max(1);
    let w = ext / n as f64;
    let cross: f64 = (0..3).filter(|&a| a != axis).map(|a| hi[a] - lo[a]).product();
    let mut vol = vec![0.0; n];
    for (x, &r) in pos.iter().zip(rad) {
        let c = x[axis];
        let k0 = (((c - r - lo[axis]) / w).floor().max(0.0) as usize).min(n - 1);
        let k1 = (((c + r - lo[axis]) / w).floor().max(0.0) as usize).min(n - 1);
        for (k, v) in vol.iter_mut().enumerate().take(k1 + 1).skip(k0) {
            let a = lo[axis] + k as f64 * w;
            *v += slab_volume(c, r, a, a + w);
        }
    }
    let centres: Vec<f64> = (0..n).map(|k| lo[axis] + (k as f64 + 0.5) * w).collect();
    let interior = (0..n)
        .map(|k| {
            let a = k as f64 * w;
            a >= interior_margin - 1e-12 * ext && ext - (a + w) >= interior_margin - 1e-12 * ext
        })
        .collect();
    Laminae { axis, centres, density: vol.iter().map(|v| v / (w * cross)).collect(), interior }
}

/// Writes the spheres as VTK XML unstructured points (ASCII `.vtu`): point data `radius`
/// [m] and `coordination`.
pub fn write_vtu(path: &Path, pos: &[Vector3<f64>], rad: &[f64], coordination: &[u32]) -> Result<(), Error> {
    let mut s = String::new();
    let n = pos.len();
    s.push_str("<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"0.1\" byte_order=\"LittleEndian\">\n<UnstructuredGrid>\n");
    s.push_str(&format!("<Piece NumberOfPoints=\"{n}\" NumberOfCells=\"{n}\">\n<Points>\n<DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">\n"));
    for x in pos {
        s.push_str(&format!("{:e} {:e} {:e}\n", x[0], x[1], x[2]));
    }
    s.push_str("</DataArray>\n</Points>\n<Cells>\n<DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">\n");
    for k in 0..n {
        s.push_str(&format!("{k}\n"));
    }
    s.push_str("</DataArray>\n<DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">\n");
    for k in 0..n {
        s.push_str(&format!("{}\n", k + 1));
    }
    s.push_str("</DataArray>\n<DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">\n");
    for _ in 0..n {
        s.push_str("1\n");
    }
    s.push_str("</DataArray>\n</Cells>\n<PointData Scalars=\"radius\">\n<DataArray type=\"Float64\" Name=\"radius\" format=\"ascii\">\n");
    for r in rad {
        s.push_str(&format!("{r:e}\n"));
    }
    s.push_str("</DataArray>\n<DataArray type=\"Int32\" Name=\"coordination\" format=\"ascii\">\n");
    for c in coordination {
        s.push_str(&format!("{c}\n"));
    }
    s.push_str("</DataArray>\n</PointData>\n</Piece>\n</UnstructuredGrid>\n</VTKFile>\n");
    std::fs::write(path, s).map_err(|e| IoError::new(path, e).into())
}

/// A minimal line plot as PNG: each series `(points, rgb)` drawn as a polyline in a frame scaled
/// to the data, plus an optional horizontal band `[lo, hi]` shaded grey. No text (labels go in
/// the CSV beside it).
pub fn write_line_plot(path: &Path, series: &[(Vec<(f64, f64)>, [u8; 3])], band: Option<(f64, f64)>) -> Result<(), Error> {
    let (w, h) = (640usize, 400usize);
    let (ml, mr, mt, mb) = (40usize, 20usize, 20usize, 40usize);
    let mut img = vec![255u8; w * h * 3];
    let (mut x0, mut x1, mut y0, mut y1) = (f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY);
    for (pts, _) in series {
        for &(x, y) in pts {
            if x.is_finite() && y.is_finite() {
                x0 = x0.min(x);
                x1 = x1.max(x);
                y0 = y0.min(y);
                y1 = y1.max(y);
            }
        }
    }
    if let Some((a, b)) = band {
        y0 = y0.min(a);
        y1 = y1.max(b);
    }
    if !(x1 > x0) {
        x1 = x0 + 1.0;
    }
    if !(y1 > y0) {
        y1 = y0 + 1.0;
    }
    let pad = 0.05 * (y1 - y0);
    let (y0, y1) = (y0 - pad, y1 + pad);
    let px = |x: f64| ml as f64 + (x - x0) / (x1 - x0) * (w - ml - mr) as f64;
    let py = |y: f64| (h - mb) as f64 - (y - y0) / (y1 - y0) * (h - mt - mb) as f64;
    let put = |img: &mut Vec<u8>, x: i64, y: i64, c: [u8; 3]| {
        if x >= 0 && y >= 0 && (x as usize) < w && (y as usize) < h {
            let o = (y as usize * w + x as usize) * 3;
            img[o..o + 3].copy_from_slice(&c);
        }
    };
    if let Some((a, b)) = band {
        let (ya, yb) = (py(b) as i64, py(a) as i64);
        for y in ya..=yb {
            for x in ml as i64..(w - mr) as i64 {
                put(&mut img, x, y, [225, 225, 225]);
            }
        }
    }
    // frame
    for x in ml..w - mr {
        put(&mut img, x as i64, (h - mb) as i64, [0, 0, 0]);
        put(&mut img, x as i64, mt as i64, [0, 0, 0]);
    }
    for y in mt..=h - mb {
        put(&mut img, ml as i64, y as i64, [0, 0, 0]);
        put(&mut img, (w - mr) as i64, y as i64, [0, 0, 0]);
    }
    for (pts, c) in series {
        for seg in pts.windows(2) {
            let (ax, ay, bx, by) = (px(seg[0].0), py(seg[0].1), px(seg[1].0), py(seg[1].1));
            let steps = ((bx - ax).abs().max((by - ay).abs()).ceil() as usize).max(1);
            for s in 0..=steps {
                let t = s as f64 / steps as f64;
                let (x, y) = ((ax + t * (bx - ax)).round() as i64, (ay + t * (by - ay)).round() as i64);
                for d in [(0, 0), (1, 0), (0, 1)] {
                    put(&mut img, x + d.0, y + d.1, *c);
                }
            }
        }
    }
    std::fs::write(path, encode_png(w, h, &img)).map_err(|e| IoError::new(path, e).into())
}

fn crc32(data: &[u8]) -> u32 {
    let mut c = 0xFFFF_FFFFu32;
    for &b in data {
        c ^= b as u32;
        for _ in 0..8 {
            c = if c & 1 != 0 { 0xEDB8_8320 ^ (c >> 1) } else { c >> 1 };
        }
    }
    !c
}

/// RGB8 PNG with an uncompressed (stored-block) zlib stream.
fn encode_png(w: usize, h: usize, rgb: &[u8]) -> Vec<u8> {
    let mut raw = Vec::with_capacity(h * (w * 3 + 1));
    for y in 0..h {
        raw.push(0u8);
        raw.extend_from_slice(&rgb[y * w * 3..(y + 1) * w * 3]);
    }
    let mut z = vec![0x78u8, 0x01];
    let blocks: Vec<&[u8]> = raw.chunks(65535).collect();
    for (k, b) in blocks.iter().enumerate() {
        z.push(if k + 1 == blocks.len() { 1 } else { 0 });
        let len = b.len() as u16;
        z.extend_from_slice(&len.to_le_bytes());
        z.extend_from_slice(&(!len).to_le_bytes());
        z.extend_from_slice(b);
    }
    let (mut a, mut bsum) = (1u32, 0u32);
    for &x in &raw {
        a = (a + x as u32) % 65521;
        bsum = (bsum + a) % 65521;
    }
    z.extend_from_slice(&((bsum << 16) | a).to_be_bytes());
    let mut png = vec![0x89, b'P', b'N', b'G', 0x0D, 0x0A, 0x1A, 0x0A];
    let chunk = |png: &mut Vec<u8>, ty: &[u8; 4], data: &[u8]| {
        png.extend_from_slice(&(data.len() as u32).to_be_bytes());
        let mut c = ty.to_vec();
        c.extend_from_slice(data);
        png.extend_from_slice(&c);
        png.extend_from_slice(&crc32(&c).to_be_bytes());
    };
    let mut ihdr = Vec::new();
    ihdr.extend_from_slice(&(w as u32).to_be_bytes());
    ihdr.extend_from_slice(&(h as u32).to_be_bytes());
    ihdr.extend_from_slice(&[8, 2, 0, 0, 0]);
    chunk(&mut png, b"IHDR", &ihdr);
    chunk(&mut png, b"IDAT", &z);
    chunk(&mut png, b"IEND", &[]);
    png
}

/// Writes text to a file, naming the path on failure.
pub fn write_text(path: &Path, text: &str) -> Result<(), Error> {
    let mut f = std::fs::File::create(path).map_err(|e| IoError::new(path, e))?;
    f.write_all(text.as_bytes()).map_err(|e| IoError::new(path, e).into())
}

#[cfg(test)]
mod tests {
    use super::*;
    #[test]
    fn slab_volumes_add_up_to_the_sphere() {
        let r = 2.0;
        let full = crate::units::sphere_volume(r);
        assert!((slab_volume(0.3, r, -10.0, 10.0) - full).abs() < 1e-12 * full);
        let parts: f64 = (0..7).map(|k| slab_volume(0.3, r, -3.0 + k as f64, -2.0 + k as f64)).sum();
        assert!((parts - full).abs() < 1e-12 * full);
        // a hemisphere
        assert!((slab_volume(0.0, r, 0.0, 5.0) - 0.5 * full).abs() < 1e-12);
    }
}
