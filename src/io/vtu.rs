//! VTK XML unstructured-grid snapshots (ASCII, readable by ParaView and meshio) and the PVD
//! time index. Particles are points (one VTK_VERTEX cell each) with radius and temperature;
//! contacts are lines between particle centres with their data as cell data.

use super::Snapshot;
use crate::error::IoError;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

const VTK_VERTEX: u8 = 1;
const VTK_LINE: u8 = 3;

fn data_array(out: &mut String, name: &str, comps: usize, values: impl Iterator<Item = f64>) {
    if comps > 1 {
        let _ = writeln!(out, "<DataArray type=\"Float64\" Name=\"{name}\" NumberOfComponents=\"{comps}\" format=\"ascii\">");
    } else {
        let _ = writeln!(out, "<DataArray type=\"Float64\" Name=\"{name}\" format=\"ascii\">");
    }
    for (k, v) in values.enumerate() {
        let _ = write!(out, "{v:e}");
        out.push(if (k + 1) % 9 == 0 { '\n' } else { ' ' });
    }
    out.push_str("\n</DataArray>\n");
}

fn int_array(out: &mut String, name: &str, ty: &str, values: impl Iterator<Item = u64>) {
    let _ = writeln!(out, "<DataArray type=\"{ty}\" Name=\"{name}\" format=\"ascii\">");
    for (k, v) in values.enumerate() {
        let _ = write!(out, "{v}");
        out.push(if (k + 1) % 16 == 0 { '\n' } else { ' ' });
    }
    out.push_str("\n</DataArray>\n");
}

/// Renders a grid with the given points and cells (`cells[k]` = point indices, `types[k]`).
fn grid(points: &[nalgebra::Vector3<f64>], cells: &[Vec<u64>], types: &[u8], point_data: &[(&str, &[f64])], cell_data: &[(&str, &[f64])]) -> String {
    let mut s = String::with_capacity(64 * points.len() + 64 * cells.len());
    s.push_str("<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt64\">\n<UnstructuredGrid>\n");
    let _ = write!(s, "<Piece NumberOfPoints=\"{}\" NumberOfCells=\"{}\">\n<Points>\n", points.len(), cells.len());
    data_array(&mut s, "Points", 3, points.iter().flat_map(|p| [p.x, p.y, p.z]));
    s.push_str("</Points>\n<Cells>\n");
    int_array(&mut s, "connectivity", "Int64", cells.iter().flatten().copied());
    let mut off = 0u64;
    int_array(&mut s, "offsets", "Int64", cells.iter().map(|c| {
        off += c.len() as u64;
        off
    }));
    int_array(&mut s, "types", "UInt8", types.iter().map(|&t| t as u64));
    s.push_str("</Cells>\n<PointData>\n");
    for (name, v) in point_data {
        data_array(&mut s, name, 1, v.iter().copied());
    }
    s.push_str("</PointData>\n<CellData>\n");
    for (name, v) in cell_data {
        data_array(&mut s, name, 1, v.iter().copied());
    }
    s.push_str("</CellData>\n</Piece>\n</UnstructuredGrid>\n</VTKFile>\n");
    s
}

/// Writes `particles_NNNNNN.vtu` and `contacts_NNNNNN.vtu` in `dir`.
pub fn write_snapshot(dir: &Path, index: usize, snap: &Snapshot) -> Result<(PathBuf, PathBuf), IoError> {
    let n = snap.position.len();
    let cells: Vec<Vec<u64>> = (0..n as u64).map(|i| vec![i]).collect();
    let types = vec![VTK_VERTEX; n];
    // an athermal scene (packing generation) passes no temperatures: the array is left out
    let mut pd: Vec<(&str, &[f64])> = vec![("radius_m", snap.radius)];
    if !snap.temperature.is_empty() {
        pd.push(("temperature_K", snap.temperature));
    }
    pd.extend(snap.particle_data.iter().copied());
    let p_path = dir.join(format!("particles_{index:06}.vtu"));
    std::fs::write(&p_path, grid(snap.position, &cells, &types, &pd, &[])).map_err(|e| IoError::new(&p_path, e))?;
    let lines: Vec<Vec<u64>> = snap.contacts.iter().map(|c| vec![c[0] as u64, c[1] as u64]).collect();
    let ltypes = vec![VTK_LINE; lines.len()];
    let c_path = dir.join(format!("contacts_{index:06}.vtu"));
    std::fs::write(&c_path, grid(snap.position, &lines, &ltypes, &pd[1..], &snap.contact_data)).map_err(|e| IoError::new(&c_path, e))?;
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
            std::fs::write(&path, s).map_err(|e| IoError::new(&path, e))?;
        }
        Ok(())
    }
}
