//! HDF5 output (`DIR/sinterdem.h5`) in the H5MD 1.1 layout (de Buyl, Colberg and Höfling 2014;
//! the layout LAMMPS `dump h5md` writes); docs/outputs.md has the tree and a Python example.
//!
//! - `/h5md` (attribute `version` = [1, 1]) with `author` (`name`) and `creator` (`name`,
//!   `version`);
//! - `/particles/all`: `box` (`dimension` = 3, `boundary` = none), `id` (time-independent), and
//!   one time-dependent element per quantity (`position`, `radius`, `temperature`, `coordination`,
//!   `displacement`, ...), each a group with `value` [snapshot, particle(, 3)], `step` and `time`;
//! - `/contacts` (sinterdem's own group, allowed by H5MD next to its modules): `count` (contacts
//!   at each snapshot) and `pairs` [snapshot, contact, 2] plus one element per contact quantity
//!   (`neck_radius`, ...) [snapshot, contact]; the number of contacts changes, so the contact axis
//!   has the largest count so far and rows at and after `count` hold the fill value (-1 for
//!   `pairs`, NaN for the others);
//! - `/observables`: the columns of `series.csv` as time-dependent elements (`value`, `time`,
//!   `step` = row number of the series), written when the run ends;
//! - `/parameters`: `case_toml` (the case as run), `materials_json`, `sinterdem_version`;
//!   `/summary`: `json` (summary.json) and one scalar dataset per numeric summary entry.
//!
//! Every dataset has a `unit` attribute (the H5MD units module; SI strings, "1" for
//! dimensionless values and counts) and the same string as `units`. Time-dependent datasets are
//! chunked (one snapshot per chunk), shuffled and deflate-compressed.
//!
//! Needs the `h5` cargo feature (system library libhdf5, Debian package `libhdf5-dev`); without it
//! the writer reports [`H5Error::Disabled`] and the run logs [`DISABLED_MESSAGE`].

use super::Snapshot;
use crate::error::IoError;
use std::path::Path;

pub const DISABLED_MESSAGE: &str = "HDF5 output is off: this binary was built without the `h5` feature (build with `cargo build --release --features h5` after installing libhdf5-dev and pkg-config); VTU and CSV output are unaffected";

#[derive(Debug)]
pub enum H5Error {
    Disabled,
    Io(IoError),
}

/// Splits a name with its unit suffix (`neck_radius_m`) into the H5MD element name and an SI unit
/// string (`neck_radius`, `m`); names without a known suffix are dimensionless (`1`).
pub fn split_unit(name: &str) -> (&str, &'static str) {
    const SUFFIXES: [(&str, &str); 15] = [
        ("_seconds", "s"),
        ("_W_per_mK", "W m-1 K-1"),
        ("_W_per_K", "W K-1"),
        ("_m_per_s", "m s-1"),
        ("_K_per_min", "K min-1"),
        ("_N_per_m", "N m-1"),
        ("_Pa", "Pa"),
        ("_J", "J"),
        ("_W", "W"),
        ("_N", "N"),
        ("_K", "K"),
        ("_s", "s"),
        ("_m", "m"),
        ("_m2", "m2"),
        ("_m3", "m3"),
    ];
    for (suf, unit) in SUFFIXES {
        if let Some(base) = name.strip_suffix(suf)
            && !base.is_empty()
        {
            return (base, unit);
        }
    }
    if name.starts_with("seconds_") {
        return (name, "s");
    }
    (name, "1")
}

#[cfg(feature = "h5")]
mod imp {
    use super::*;
    use hdf5_metno::types::VarLenUnicode;
    use hdf5_metno::{Dataset, File, Group, H5Type};
    use std::str::FromStr;

    type R<T> = Result<T, hdf5_metno::Error>;

    fn text(s: &str) -> VarLenUnicode {
        // VarLenUnicode refuses interior NUL bytes only
        VarLenUnicode::from_str(&s.replace('\0', " ")).unwrap_or_else(|_| VarLenUnicode::from_str("").expect("empty string"))
    }

    pub(super) fn group(parent: &Group, name: &str) -> R<Group> {
        if parent.link_exists(name) { parent.group(name) } else { parent.create_group(name) }
    }

    fn str_attr(loc: &hdf5_metno::Location, name: &str, value: &str) -> R<()> {
        if loc.attr_names()?.iter().any(|a| a == name) {
            return Ok(());
        }
        loc.new_attr::<VarLenUnicode>().shape(()).create(name)?.write_scalar(&text(value))
    }

    /// Sets `unit` (H5MD) and `units` on a dataset.
    fn unit(ds: &Dataset, u: &str) -> R<()> {
        str_attr(ds, "unit", u)?;
        str_attr(ds, "units", u)
    }

    fn str_dataset(g: &Group, name: &str, value: &str) -> R<()> {
        if g.link_exists(name) {
            g.unlink(name)?;
        }
        let ds = g.new_dataset::<VarLenUnicode>().shape(()).create(name)?;
        ds.write_scalar(&text(value))?;
        unit(&ds, "1")
    }

    /// The `/h5md` header.
    pub(super) fn header(file: &File) -> R<()> {
        let h = group(file, "h5md")?;
        if !h.attr_names()?.iter().any(|a| a == "version") {
            h.new_attr_builder().with_data(&[1i32, 1]).create("version")?;
        }
        let author = std::env::var("USER").ok().filter(|u| !u.is_empty()).unwrap_or_else(|| "unknown".into());
        let a = group(&h, "author")?;
        str_attr(&a, "name", &author)?;
        let c = group(&h, "creator")?;
        str_attr(&c, "name", "sinterdem")?;
        str_attr(&c, "version", env!("CARGO_PKG_VERSION"))?;
        let all = group(&group(file, "particles")?, "all")?;
        let b = group(&all, "box")?;
        if !b.attr_names()?.iter().any(|a| a == "dimension") {
            b.new_attr::<i32>().shape(()).create("dimension")?.write_scalar(&3)?;
            b.new_attr_builder().with_data(&[text("none"), text("none"), text("none")]).create("boundary")?;
        }
        group(file, "contacts")?;
        Ok(())
    }

    /// A time-dependent element: appends one entry (`row`, of shape `inner`) at `step`/`time`.
    /// The first axis of `value` is the snapshot; a `grow` axis (the contact axis) is resized to
    /// the largest count so far, the rest holds `fill`.
    fn append<T: H5Type + Copy>(parent: &Group, name: &str, u: &str, inner: &[usize], row: &[T], fill: T, step: u64, time: f64) -> R<()> {
        let g = group(parent, name)?;
        let value = if g.link_exists("value") {
            g.dataset("value")?
        } else {
            let mut chunk = vec![1usize];
            // one snapshot per chunk; at most ~2 MB per chunk for large packings
            let cap = (262_144 / inner.iter().skip(1).product::<usize>().max(1)).max(1);
            chunk.extend(inner.iter().enumerate().map(|(k, &d)| if k == 0 { d.clamp(1, cap) } else { d.max(1) }));
            let mut shape: Vec<hdf5_metno::Extent> = vec![hdf5_metno::Extent::resizable(0)];
            shape.extend(inner.iter().enumerate().map(|(k, &d)| if k == 0 { hdf5_metno::Extent::resizable(0) } else { hdf5_metno::Extent::fixed(d) }));
            let ds = g.new_dataset::<T>().chunk(chunk).shuffle().deflate(4).fill_value(fill).shape(shape).create("value")?;
            unit(&ds, u)?;
            for (n, ty_int) in [("step", true), ("time", false)] {
                let b = if ty_int { g.new_dataset::<i64>() } else { g.new_dataset::<f64>() };
                let d = b.chunk(vec![256usize]).shape(vec![hdf5_metno::Extent::resizable(0)]).create(n)?;
                unit(&d, if ty_int { "1" } else { "s" })?;
            }
            ds
        };
        let old = value.shape();
        let k = old[0];
        let mut new = old.clone();
        new[0] = k + 1;
        if !inner.is_empty() {
            new[1] = old[1].max(inner[0]);
        }
        value.resize(new.clone())?;
        let n: usize = inner.iter().product();
        if n > 0 {
            let mut dims = vec![1usize];
            dims.extend_from_slice(inner);
            let arr = ndarray::ArrayView::from_shape(ndarray::IxDyn(&dims), row)?;
            let mut sel: Vec<hdf5_metno::SliceOrIndex> = vec![hdf5_metno::SliceOrIndex::SliceTo { start: k, step: 1, end: k + 1, block: 1 }];
            for &d in inner {
                sel.push(hdf5_metno::SliceOrIndex::SliceTo { start: 0, step: 1, end: d, block: 1 });
            }
            value.write_slice(arr, hdf5_metno::Hyperslab::from(sel))?;
        }
        let sd = g.dataset("step")?;
        sd.resize(vec![k + 1])?;
        sd.write_slice(&[step as i64], k..k + 1)?;
        let td = g.dataset("time")?;
        td.resize(vec![k + 1])?;
        td.write_slice(&[time], k..k + 1)?;
        Ok(())
    }

    pub(super) fn write_snapshot(file: &File, s: &Snapshot) -> R<()> {
        header(file)?;
        let (t, st) = (s.time, s.step);
        let n = s.position.len();
        let all = file.group("particles/all")?;
        if !all.link_exists("id") {
            let ids: Vec<i64> = (0..n as i64).collect();
            let ds = all.new_dataset_builder().with_data(&ids).create("id")?;
            unit(&ds, "1")?;
        }
        let pos: Vec<f64> = s.position.iter().flat_map(|p| [p.x, p.y, p.z]).collect();
        append(&all, "position", "m", &[n, 3], &pos, f64::NAN, st, t)?;
        append(&all, "radius", "m", &[n], s.radius, f64::NAN, st, t)?;
        if !s.temperature.is_empty() {
            append(&all, "temperature", "K", &[n], s.temperature, f64::NAN, st, t)?;
        }
        let z = super::super::vtu::coordination(n, s.contacts);
        append(&all, "coordination", "1", &[n], &z, -1, st, t)?;
        for (name, v) in &s.particle_data {
            let (base, u) = split_unit(name);
            append(&all, base, u, &[n], v, f64::NAN, st, t)?;
        }
        for (name, v) in &s.particle_vectors {
            let (base, u) = split_unit(name);
            let flat: Vec<f64> = v.iter().flat_map(|p| [p.x, p.y, p.z]).collect();
            append(&all, base, u, &[n, 3], &flat, f64::NAN, st, t)?;
        }
        let c = file.group("contacts")?;
        let m = s.contacts.len();
        append(&c, "count", "1", &[], &[m as i64], -1, st, t)?;
        let pairs: Vec<i64> = s.contacts.iter().flat_map(|p| [p[0] as i64, p[1] as i64]).collect();
        append(&c, "pairs", "1", &[m, 2], &pairs, -1, st, t)?;
        for (name, v) in &s.contact_data {
            let (base, u) = split_unit(name);
            append(&c, base, u, &[m], v, f64::NAN, st, t)?;
        }
        if let Some(p) = &s.parameters
            && !file.link_exists("parameters")
        {
            let g = file.create_group("parameters")?;
            str_dataset(&g, "case_toml", &p.case_toml)?;
            str_dataset(&g, "materials_json", &p.materials_json)?;
            str_dataset(&g, "sinterdem_version", env!("CARGO_PKG_VERSION"))?;
        }
        Ok(())
    }

    /// Elements (groups with a `value`) under `g`, recursively.
    fn elements(g: &Group, out: &mut Vec<Group>) -> R<()> {
        for name in g.member_names()? {
            if let Ok(sub) = g.group(&name) {
                if sub.link_exists("value") && sub.link_exists("step") {
                    out.push(sub);
                } else {
                    elements(&sub, out)?;
                }
            }
        }
        Ok(())
    }

    /// Keeps the first `keep` entries of every time-dependent element; drops what a finished run
    /// adds (`/observables`, `/summary`).
    pub(super) fn trim(file: &File, keep: usize) -> R<()> {
        if !file.link_exists("h5md") || !file.link_exists("particles") {
            return Err("not an H5MD file written by sinterdem".into());
        }
        for gone in ["observables", "summary"] {
            if file.link_exists(gone) {
                file.unlink(gone)?;
            }
        }
        let mut els = Vec::new();
        elements(&file.group("particles")?, &mut els)?;
        elements(&file.group("contacts")?, &mut els)?;
        for g in els {
            for name in ["value", "step", "time"] {
                let d = g.dataset(name)?;
                let mut shape = d.shape();
                if shape[0] > keep {
                    shape[0] = keep;
                    d.resize(shape)?;
                }
            }
        }
        Ok(())
    }

    /// `/observables` from `series.csv` and `/summary` from `summary.json` of `dir`.
    pub(super) fn finish(file: &File, dir: &Path) -> R<()> {
        header(file)?;
        if let Ok(text) = std::fs::read_to_string(dir.join("series.csv")) {
            if file.link_exists("observables") {
                file.unlink("observables")?;
            }
            let obs = file.create_group("observables")?;
            let mut lines = text.lines();
            let head: Vec<&str> = lines.next().unwrap_or("").split(',').collect();
            let rows: Vec<Vec<f64>> = lines.map(|l| l.split(',').map(|v| v.trim().parse().unwrap_or(f64::NAN)).collect()).collect();
            let time: Vec<f64> = rows.iter().map(|r| r.first().copied().unwrap_or(f64::NAN)).collect();
            let steps: Vec<i64> = (0..rows.len() as i64).collect();
            for (k, name) in head.iter().enumerate().skip(1) {
                let (base, u) = split_unit(name);
                let g = obs.create_group(base)?;
                let col: Vec<f64> = rows.iter().map(|r| r.get(k).copied().unwrap_or(f64::NAN)).collect();
                let ds = if super::super::is_count_column(name) {
                    let v: Vec<i64> = col.iter().map(|&x| if x.is_finite() { x.round() as i64 } else { -1 }).collect();
                    g.new_dataset_builder().with_data(&v).chunk(v.len().max(1)).deflate(4).create("value")?
                } else {
                    g.new_dataset_builder().with_data(&col).chunk(col.len().max(1)).shuffle().deflate(4).create("value")?
                };
                unit(&ds, u)?;
                let d = g.new_dataset_builder().with_data(&time).chunk(time.len().max(1)).deflate(4).create("time")?;
                unit(&d, "s")?;
                let d = g.new_dataset_builder().with_data(&steps).chunk(steps.len().max(1)).deflate(4).create("step")?;
                unit(&d, "1")?;
            }
        }
        if let Ok(text) = std::fs::read_to_string(dir.join("summary.json")) {
            if file.link_exists("summary") {
                file.unlink("summary")?;
            }
            let g = file.create_group("summary")?;
            str_dataset(&g, "json", &text)?;
            if let Ok(serde_json::Value::Object(map)) = serde_json::from_str::<serde_json::Value>(&text) {
                for (key, v) in map {
                    let (_, u) = split_unit(&key);
                    let ds = if let Some(i) = v.as_i64().filter(|_| v.is_i64() || v.is_u64()) {
                        let d = g.new_dataset::<i64>().shape(()).create(key.as_str())?;
                        d.write_scalar(&i)?;
                        d
                    } else if let Some(x) = v.as_f64() {
                        let d = g.new_dataset::<f64>().shape(()).create(key.as_str())?;
                        d.write_scalar(&x)?;
                        d
                    } else {
                        continue;
                    };
                    unit(&ds, u)?;
                }
            }
        }
        Ok(())
    }
}

/// Writes snapshots into one HDF5 file. The file is open only while a snapshot is written (created,
/// written, flushed, closed), so a run killed between snapshots leaves a consistent file that a
/// resumed run can reopen.
#[cfg(feature = "h5")]
pub struct H5Writer {
    path: std::path::PathBuf,
    /// What the reopening had to do, for the run's log.
    pub note: Option<String>,
}

#[cfg(feature = "h5")]
impl H5Writer {
    pub fn create(path: &Path) -> Result<Self, H5Error> {
        let err = |e: hdf5_metno::Error| H5Error::Io(IoError::new(path, e));
        crate::io::manifest::record(path).map_err(H5Error::Io)?;
        let file = hdf5_metno::File::create(path).map_err(err)?;
        imp::header(&file).map_err(err)?;
        file.close().map_err(err)?;
        Ok(H5Writer { path: path.to_path_buf(), note: None })
    }

    /// Reopens the file of an interrupted run, keeping its first `keep` snapshots (those before
    /// the checkpoint). A file that cannot be read (the run was killed while writing a snapshot)
    /// is moved to `<name>.damaged` and a new one started; `note` says so.
    pub fn reopen(path: &Path, keep: usize) -> Result<Self, H5Error> {
        if !path.exists() {
            return Self::create(path);
        }
        let trim = || -> Result<(), hdf5_metno::Error> {
            let file = hdf5_metno::File::open_rw(path)?;
            imp::trim(&file, keep)?;
            file.close()
        };
        match trim() {
            Ok(()) => Ok(H5Writer { path: path.to_path_buf(), note: None }),
            Err(e) => {
                let moved = path.with_extension("h5.damaged");
                crate::io::manifest::record(&moved).map_err(H5Error::Io)?;
                std::fs::rename(path, &moved).map_err(|io| H5Error::Io(IoError::new(path, io)))?;
                let mut w = Self::create(path)?;
                w.note = Some(format!(
                    "warning: {} could not be reopened ({e}); moved to {} and a new file started: its snapshots before the checkpoint are in the VTU files only",
                    path.display(),
                    moved.display()
                ));
                Ok(w)
            }
        }
    }

    pub fn write(&mut self, _index: usize, s: &Snapshot) -> Result<(), IoError> {
        let err = |e: hdf5_metno::Error| IoError::new(&self.path, e);
        let file = hdf5_metno::File::open_rw(&self.path).map_err(err)?;
        imp::write_snapshot(&file, s).map_err(err)?;
        file.close().map_err(err)?;
        Ok(())
    }
}

/// At the end of a run: adds `series.csv` (as `/observables`) and `summary.json` (as `/summary`)
/// of `dir` to `dir/sinterdem.h5`. Does nothing if the file is absent or HDF5 is off.
#[cfg(feature = "h5")]
pub fn finish(dir: &Path) -> Result<(), IoError> {
    let path = dir.join("sinterdem.h5");
    if !path.exists() {
        return Ok(());
    }
    let err = |e: hdf5_metno::Error| IoError::new(&path, e);
    let file = hdf5_metno::File::open_rw(&path).map_err(err)?;
    imp::finish(&file, dir).map_err(err)?;
    file.close().map_err(err)
}

#[cfg(not(feature = "h5"))]
pub fn finish(_dir: &Path) -> Result<(), IoError> {
    Ok(())
}

#[cfg(not(feature = "h5"))]
pub struct H5Writer {
    pub note: Option<String>,
}

#[cfg(not(feature = "h5"))]
impl H5Writer {
    pub fn create(_path: &Path) -> Result<Self, H5Error> {
        Err(H5Error::Disabled)
    }

    pub fn reopen(_path: &Path, _keep: usize) -> Result<Self, H5Error> {
        Err(H5Error::Disabled)
    }

    pub fn write(&mut self, _index: usize, _s: &Snapshot) -> Result<(), IoError> {
        Ok(())
    }
}

/// Whether this binary writes HDF5.
pub const ENABLED: bool = cfg!(feature = "h5");

#[cfg(test)]
mod tests {
    #[test]
    fn unit_suffixes() {
        assert_eq!(super::split_unit("neck_radius_m"), ("neck_radius", "m"));
        assert_eq!(super::split_unit("conductance_W_per_K"), ("conductance", "W K-1"));
        assert_eq!(super::split_unit("shrinkage_x"), ("shrinkage_x", "1"));
        assert_eq!(super::split_unit("time_s"), ("time", "s"));
        assert_eq!(super::split_unit("contacts"), ("contacts", "1"));
    }
}
