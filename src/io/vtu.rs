//! VTK XML unstructured-grid snapshots and the PVD time index (docs/outputs.md).
//!
//! Binary arrays, zlib-compressed and base64-encoded inline (`format="binary"`,
//! `compressor="vtkZLibDataCompressor"`, `header_type="UInt64"`: per array a base64 header
//! [blocks, block size, last block size, compressed size of each block] followed by the base64
//! of the compressed blocks), as VTK itself writes them; ParaView, VTK and meshio read them and the
//! file stays well-formed XML.
//!
//! `particles_NNNNNN.vtu`: particles as points (one VTK_VERTEX cell each) with point data `id`,
//! `coordination` (contacts per particle; Int32), `radius_m`, `temperature_K` (if the kind has
//! temperatures), the kind's vector arrays (`displacement_m`, 3 components) and scalar arrays.
//! `contacts_NNNNNN.vtu`: the same points (no point data), contacts as lines with their data as
//! cell data: `particle_a`, `particle_b` (Int32) and the kind's arrays (`neck_radius_m`, ...).

use super::Snapshot;
use crate::error::IoError;
use std::fmt::Write as _;
use std::io::Write as _;
use std::path::{Path, PathBuf};

const VTK_VERTEX: u8 = 1;
const VTK_LINE: u8 = 3;

/// Standard base64 (RFC 4648, with padding).
pub fn base64(bytes: &[u8]) -> String {
    const A: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut s = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for c in bytes.chunks(3) {
        let b = [c[0], *c.get(1).unwrap_or(&0), *c.get(2).unwrap_or(&0)];
        let n = (b[0] as u32) << 16 | (b[1] as u32) << 8 | b[2] as u32;
        s.push(A[(n >> 18) as usize & 63] as char);
        s.push(A[(n >> 12) as usize & 63] as char);
        s.push(if c.len() > 1 { A[(n >> 6) as usize & 63] as char } else { '=' });
        s.push(if c.len() > 2 { A[n as usize & 63] as char } else { '=' });
    }
    s
}

/// One array's values as little-endian bytes.
enum Values<'a> {
    F64(Box<dyn Iterator<Item = f64> + 'a>),
    I32(Box<dyn Iterator<Item = i32> + 'a>),
    U8(Box<dyn Iterator<Item = u8> + 'a>),
}

/// Uncompressed bytes per zlib block.
const BLOCK: usize = 1 << 16;

/// The base64 header and data of a zlib-compressed VTK array.
fn compressed(bytes: &[u8]) -> String {
    let blocks: Vec<&[u8]> = if bytes.is_empty() { vec![&[][..]] } else { bytes.chunks(BLOCK).collect() };
    let packed: Vec<Vec<u8>> = blocks
        .iter()
        .map(|b| {
            let mut z = flate2::write::ZlibEncoder::new(Vec::with_capacity(b.len() / 2 + 16), flate2::Compression::default());
            // writing into a Vec cannot fail
            let _ = z.write_all(b);
            z.finish().unwrap_or_default()
        })
        .collect();
    let mut header: Vec<u64> = vec![blocks.len() as u64, BLOCK as u64, blocks.last().map_or(0, |b| b.len()) as u64];
    header.extend(packed.iter().map(|p| p.len() as u64));
    let hb: Vec<u8> = header.iter().flat_map(|v| v.to_le_bytes()).collect();
    base64(&hb) + &base64(&packed.concat())
}

fn data_array(out: &mut String, name: &str, comps: usize, values: Values) {
    let (ty, bytes): (&str, Vec<u8>) = match values {
        Values::F64(it) => ("Float64", it.flat_map(|v| v.to_le_bytes()).collect()),
        Values::I32(it) => ("Int32", it.flat_map(|v| v.to_le_bytes()).collect()),
        Values::U8(it) => ("UInt8", it.collect()),
    };
    let comps = if comps > 1 { format!(" NumberOfComponents=\"{comps}\"") } else { String::new() };
    let _ = writeln!(out, "<DataArray type=\"{ty}\" Name=\"{name}\"{comps} format=\"binary\">\n{}\n</DataArray>", compressed(&bytes));
}

/// Point or cell data of a grid.
#[derive(Default)]
struct Data<'a> {
    scalars: Vec<(&'a str, &'a [f64])>,
    vectors: Vec<(&'a str, &'a [nalgebra::Vector3<f64>])>,
    ints: Vec<(&'a str, Vec<i32>)>,
}

impl Data<'_> {
    fn write(&self, s: &mut String) {
        for (name, v) in &self.ints {
            data_array(s, name, 1, Values::I32(Box::new(v.iter().copied())));
        }
        for (name, v) in &self.scalars {
            data_array(s, name, 1, Values::F64(Box::new(v.iter().copied())));
        }
        for (name, v) in &self.vectors {
            data_array(s, name, 3, Values::F64(Box::new(v.iter().flat_map(|p| [p.x, p.y, p.z]))));
        }
    }
}

/// Renders a grid with the given points and cells (each `nodes` point indices, all of `cell_type`).
fn grid(points: &[nalgebra::Vector3<f64>], cells: &[u32], nodes: usize, cell_type: u8, point_data: &Data, cell_data: &Data) -> String {
    let n_cells = cells.len() / nodes;
    let mut s = String::with_capacity(48 * points.len() + 40 * n_cells);
    s.push_str("<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt64\" compressor=\"vtkZLibDataCompressor\">\n<UnstructuredGrid>\n");
    let _ = write!(s, "<Piece NumberOfPoints=\"{}\" NumberOfCells=\"{n_cells}\">\n<Points>\n", points.len());
    data_array(&mut s, "Points", 3, Values::F64(Box::new(points.iter().flat_map(|p| [p.x, p.y, p.z]))));
    s.push_str("</Points>\n<Cells>\n");
    data_array(&mut s, "connectivity", 1, Values::I32(Box::new(cells.iter().map(|&c| c as i32))));
    data_array(&mut s, "offsets", 1, Values::I32(Box::new((1..=n_cells).map(|k| (k * nodes) as i32))));
    data_array(&mut s, "types", 1, Values::U8(Box::new(std::iter::repeat_n(cell_type, n_cells))));
    s.push_str("</Cells>\n<PointData>\n");
    point_data.write(&mut s);
    s.push_str("</PointData>\n<CellData>\n");
    cell_data.write(&mut s);
    s.push_str("</CellData>\n</Piece>\n</UnstructuredGrid>\n</VTKFile>\n");
    s
}

/// Contacts per particle.
pub fn coordination(n: usize, contacts: &[[u32; 2]]) -> Vec<i32> {
    let mut z = vec![0i32; n];
    for &[a, b] in contacts {
        z[a as usize] += 1;
        z[b as usize] += 1;
    }
    z
}

/// Writes `particles_NNNNNN.vtu` and `contacts_NNNNNN.vtu` in `dir`.
pub fn write_snapshot(dir: &Path, index: usize, snap: &Snapshot) -> Result<(PathBuf, PathBuf), IoError> {
    let n = snap.position.len();
    let mut pd = Data::default();
    pd.ints.push(("id", (0..n as i32).collect()));
    pd.ints.push(("coordination", coordination(n, snap.contacts)));
    pd.scalars.push(("radius_m", snap.radius));
    // an athermal scene (packing generation) passes no temperatures: the array is left out
    if !snap.temperature.is_empty() {
        pd.scalars.push(("temperature_K", snap.temperature));
    }
    pd.scalars.extend(snap.particle_data.iter().copied());
    pd.vectors.extend(snap.particle_vectors.iter().copied());
    let p_path = dir.join(format!("particles_{index:06}.vtu"));
    let cells: Vec<u32> = (0..n as u32).collect();
    crate::io::manifest::record(&p_path)?;
    std::fs::write(&p_path, grid(snap.position, &cells, 1, VTK_VERTEX, &pd, &Data::default())).map_err(|e| IoError::new(&p_path, e))?;
    let lines: Vec<u32> = snap.contacts.iter().flat_map(|c| [c[0], c[1]]).collect();
    let mut cd = Data::default();
    cd.ints.push(("particle_a", snap.contacts.iter().map(|c| c[0] as i32).collect()));
    cd.ints.push(("particle_b", snap.contacts.iter().map(|c| c[1] as i32).collect()));
    cd.scalars.extend(snap.contact_data.iter().copied());
    let c_path = dir.join(format!("contacts_{index:06}.vtu"));
    crate::io::manifest::record(&c_path)?;
    std::fs::write(&c_path, grid(snap.position, &lines, 2, VTK_LINE, &Data::default(), &cd)).map_err(|e| IoError::new(&c_path, e))?;
    Ok((p_path, c_path))
}

/// `particles.pvd` and `contacts.pvd` listing every snapshot with its time; rewritten after each
/// snapshot so that an interrupted run leaves a valid index.
pub struct PvdIndex {
    entries: Vec<(f64, String, String)>,
}

impl PvdIndex {
    pub fn new(_dir: &Path) -> Self {
        PvdIndex { entries: Vec::new() }
    }

    /// The index entries so far: (time [s], particles file, contacts file).
    pub fn entries(&self) -> &[(f64, String, String)] {
        &self.entries
    }

    /// Continues an index (resumed runs).
    pub fn with_entries(entries: Vec<(f64, String, String)>) -> Self {
        PvdIndex { entries }
    }

    pub fn write(&mut self, dir: &Path, index: usize, snap: &Snapshot) -> Result<(), IoError> {
        let (p, c) = write_snapshot(dir, index, snap)?;
        let name = |x: &Path| x.file_name().unwrap().to_string_lossy().to_string();
        self.entries.push((snap.time, name(&p), name(&c)));
        for (which, file) in [(1usize, "particles.pvd"), (2, "contacts.pvd")] {
            let mut s = String::from("<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\">\n<Collection>\n");
            for e in &self.entries {
                let f = if which == 1 { &e.1 } else { &e.2 };
                let _ = writeln!(s, "<DataSet timestep=\"{:e}\" part=\"0\" file=\"{f}\"/>", e.0);
            }
            s.push_str("</Collection>\n</VTKFile>\n");
            let path = dir.join(file);
            crate::io::manifest::record(&path)?;
            std::fs::write(&path, s).map_err(|e| IoError::new(&path, e))?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_matches_rfc4648_vectors() {
        for (a, b) in [("", ""), ("f", "Zg=="), ("fo", "Zm8="), ("foo", "Zm9v"), ("foob", "Zm9vYg=="), ("fooba", "Zm9vYmE="), ("foobar", "Zm9vYmFy")] {
            assert_eq!(base64(a.as_bytes()), b);
        }
    }
}
