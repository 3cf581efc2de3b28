//! Import of packings made elsewhere: sinterdem's CSV, LIGGGHTS/LAMMPS text dumps and Yade's
//! text export of spheres. Every malformed line is reported with its file name and line number.

use crate::error::{ConfigError, Error};
use nalgebra::Vector3;
use std::path::Path;

/// File formats [`import`] reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ImportFormat {
    /// Header line naming the columns; required `x,y,z,r` [m]; optional `material` (integer id)
    /// and `temperature` [K]. Comma-separated; `#` starts a comment line.
    Csv,
    /// LIGGGHTS/LAMMPS text dump: `ITEM: ATOMS` header naming the columns, of which `x y z radius`
    /// are required (`type` becomes the material id); the last snapshot in the file is read.
    Liggghts,
    /// Yade's text export of spheres (`yade.export.text`): whitespace-separated `x y z r` per line,
    /// `#` comment lines.
    Yade,
}

impl std::str::FromStr for ImportFormat {
    type Err = ConfigError;
    fn from_str(s: &str) -> Result<Self, ConfigError> {
        match s.to_ascii_lowercase().as_str() {
            "csv" => Ok(ImportFormat::Csv),
            "liggghts" | "lammps" | "dump" => Ok(ImportFormat::Liggghts),
            "yade" | "txt" => Ok(ImportFormat::Yade),
            _ => Err(ConfigError::invalid(format!("unknown packing format \"{s}\": expected csv, liggghts (lammps) or yade"))),
        }
    }
}

/// An imported packing (SI).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ImportedPacking {
    /// Centre positions [m].
    pub positions: Vec<Vector3<f64>>,
    /// Radii [m].
    pub radii: Vec<f64>,
    /// Material ids, if the file has them.
    pub materials: Option<Vec<u16>>,
    /// Initial temperatures [K], if the file has them.
    pub temperatures: Option<Vec<f64>>,
}

/// Reads a packing file.
pub fn import(path: &Path, format: ImportFormat) -> Result<ImportedPacking, Error> {
    let text = crate::io::read_input(path)?;
    import_str(&text, format, &path.display().to_string())
}

fn line_err(name: &str, line: usize, msg: impl std::fmt::Display) -> Error {
    ConfigError::invalid(format!("{name}, line {line}: {msg}")).into()
}

fn num(name: &str, line: usize, col: &str, s: &str) -> Result<f64, Error> {
    let v: f64 = s.trim().parse().map_err(|_| line_err(name, line, format!("column {col}: \"{}\" is not a number", s.trim())))?;
    if !v.is_finite() {
        return Err(line_err(name, line, format!("column {col}: {v} is not finite")));
    }
    Ok(v)
}

/// Checks a value of a packing file against the range table entry `key`, naming file and line.
fn ranged(name: &str, line: usize, col: &str, key: &str, v: f64) -> Result<f64, Error> {
    crate::config::check(key, v).map_err(|e| line_err(name, line, format!("column {col}: {e}")))
}

fn push_sphere(out: &mut ImportedPacking, name: &str, line: usize, x: [f64; 3], r: f64) -> Result<(), Error> {
    for (c, v) in ["x", "y", "z"].iter().zip(x) {
        ranged(name, line, c, "particles.position", v)?;
    }
    ranged(name, line, "r", "particles.radius", r)?;
    out.positions.push(Vector3::new(x[0], x[1], x[2]));
    out.radii.push(r);
    Ok(())
}

/// Parses packing text; `name` appears in error messages.
pub fn import_str(text: &str, format: ImportFormat, name: &str) -> Result<ImportedPacking, Error> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let out = match format {
        ImportFormat::Csv => parse_csv(text, name)?,
        ImportFormat::Liggghts => parse_dump(text, name)?,
        ImportFormat::Yade => parse_yade(text, name)?,
    };
    if out.radii.is_empty() {
        return Err(ConfigError::invalid(format!("{name}: no particles found")).into());
    }
    Ok(out)
}

fn parse_csv(text: &str, name: &str) -> Result<ImportedPacking, Error> {
    let mut out = ImportedPacking::default();
    let mut cols: Option<(usize, [usize; 4], Option<usize>, Option<usize>)> = None;
    for (k, raw) in text.lines().enumerate() {
        let line = k + 1;
        let l = raw.trim();
        if l.is_empty() || l.starts_with('#') {
            continue;
        }
        let fields: Vec<&str> = l.split(',').map(|s| s.trim()).collect();
        match &cols {
            None => {
                // a column is named plainly or with its unit suffix (`x` or `x_m`, `radius_m`, `temperature_K`)
                let find = |c: &str| {
                    let with_unit = |f: &&str, u: &str| f.len() == c.len() + u.len() && f.to_ascii_lowercase() == format!("{}{u}", c.to_ascii_lowercase());
                    fields.iter().position(|f| f.eq_ignore_ascii_case(c) || with_unit(f, "_m") || with_unit(f, "_k"))
                };
                let mut req = [0usize; 4];
                for (a, c) in ["x", "y", "z", "r"].iter().enumerate() {
                    req[a] = find(c)
                        .or_else(|| if *c == "r" { find("radius") } else { None })
                        .ok_or_else(|| line_err(name, line, format!("header must name columns x,y,z,r (optional material, temperature); got \"{l}\"")))?;
                }
                let mat = find("material");
                let temp = find("temperature").or_else(|| find("t"));
                if mat.is_some() {
                    out.materials = Some(Vec::new());
                }
                if temp.is_some() {
                    out.temperatures = Some(Vec::new());
                }
                cols = Some((fields.len(), req, mat, temp));
            }
            Some((ncol, req, mat, temp)) => {
                if fields.len() != *ncol {
                    return Err(line_err(name, line, format!("expected {ncol} comma-separated values, found {}", fields.len())));
                }
                let x = [num(name, line, "x", fields[req[0]])?, num(name, line, "y", fields[req[1]])?, num(name, line, "z", fields[req[2]])?];
                let r = num(name, line, "r", fields[req[3]])?;
                push_sphere(&mut out, name, line, x, r)?;
                if let (Some(c), Some(v)) = (mat, out.materials.as_mut()) {
                    let m: u16 =
                        fields[*c].parse().map_err(|_| line_err(name, line, format!("material \"{}\" is not an integer id in 0..=65535", fields[*c])))?;
                    v.push(m);
                }
                if let (Some(c), Some(v)) = (temp, out.temperatures.as_mut()) {
                    let t = ranged(name, line, "temperature", "particles.initial_temperature", num(name, line, "temperature", fields[*c])?)?;
                    v.push(t);
                }
            }
        }
    }
    if cols.is_none() {
        return Err(ConfigError::invalid(format!("{name}: empty CSV (no header x,y,z,r)")).into());
    }
    Ok(out)
}

fn parse_dump(text: &str, name: &str) -> Result<ImportedPacking, Error> {
    let lines: Vec<&str> = text.lines().collect();
    // find the last "ITEM: ATOMS" block
    let start = lines
        .iter()
        .rposition(|l| l.trim_start().starts_with("ITEM: ATOMS"))
        .ok_or_else(|| ConfigError::invalid(format!("{name}: no \"ITEM: ATOMS\" line (expected a LIGGGHTS/LAMMPS text dump)")))?;
    let header: Vec<&str> = lines[start].split_whitespace().skip(2).collect();
    let find = |c: &str| header.iter().position(|f| *f == c);
    let need = |c: &str| find(c).ok_or_else(|| line_err(name, start + 1, format!("ITEM: ATOMS must name column \"{c}\"; got \"{}\"", header.join(" "))));
    let (cx, cy, cz, cr) = (need("x")?, need("y")?, need("z")?, need("radius")?);
    let ct = find("type");
    let mut out = ImportedPacking::default();
    if ct.is_some() {
        out.materials = Some(Vec::new());
    }
    for (k, raw) in lines.iter().enumerate().skip(start + 1) {
        let line = k + 1;
        let l = raw.trim();
        if l.is_empty() {
            continue;
        }
        if l.starts_with("ITEM:") {
            break;
        }
        let f: Vec<&str> = l.split_whitespace().collect();
        if f.len() != header.len() {
            return Err(line_err(name, line, format!("expected {} values ({}), found {}", header.len(), header.join(" "), f.len())));
        }
        let x = [num(name, line, "x", f[cx])?, num(name, line, "y", f[cy])?, num(name, line, "z", f[cz])?];
        push_sphere(&mut out, name, line, x, num(name, line, "radius", f[cr])?)?;
        if let (Some(c), Some(v)) = (ct, out.materials.as_mut()) {
            let t: u16 = f[c].parse().map_err(|_| line_err(name, line, format!("type \"{}\" is not an integer", f[c])))?;
            // LIGGGHTS types start at 1; material ids at 0
            v.push(t.saturating_sub(1));
        }
    }
    Ok(out)
}

fn parse_yade(text: &str, name: &str) -> Result<ImportedPacking, Error> {
    let mut out = ImportedPacking::default();
    for (k, raw) in text.lines().enumerate() {
        let line = k + 1;
        let l = raw.trim();
        if l.is_empty() || l.starts_with('#') {
            continue;
        }
        let f: Vec<&str> = l.split_whitespace().collect();
        if f.len() < 4 {
            return Err(line_err(name, line, format!("expected 4 values x y z r, found {}", f.len())));
        }
        let x = [num(name, line, "x", f[0])?, num(name, line, "y", f[1])?, num(name, line, "z", f[2])?];
        push_sphere(&mut out, name, line, x, num(name, line, "r", f[3])?)?;
    }
    Ok(out)
}
