//! Output: time series (CSV), summaries (JSON), snapshots (VTU + PVD index, HDF5), and the
//! terminal progress bar.

pub mod hdf5;
pub mod inputs;
pub mod lock;
pub mod manifest;
pub mod outdir;
pub mod progress;
pub mod vtu;

use crate::error::IoError;
use std::io::Write;
use std::path::{Path, PathBuf};

/// Creates `dir` (and parents).
pub fn ensure_dir(dir: &Path) -> Result<(), IoError> {
    std::fs::create_dir_all(dir).map_err(|e| IoError::new(dir, e))
}

/// Largest input file read as text (case, packing, checkpoint) [bytes].
pub const MAX_INPUT_BYTES: u64 = 4 << 30;

/// Reads an input file (case, packing file, checkpoint) as UTF-8 text. Refuses what is not a
/// regular file (a FIFO would block forever, `/dev/zero` would fill the memory) and files above
/// [`MAX_INPUT_BYTES`]; a leading UTF-8 byte-order mark is dropped.
pub fn read_input(path: &Path) -> Result<String, IoError> {
    let meta = std::fs::metadata(path).map_err(|e| IoError::new(path, e))?;
    if !meta.is_file() {
        let what = if meta.is_dir() { "a directory" } else { "not a regular file (a device, FIFO or socket)" };
        return Err(IoError::new(path, format!("is {what}; an input must be a regular file")));
    }
    if meta.len() > MAX_INPUT_BYTES {
        return Err(IoError::new(path, format!("is {} bytes; inputs above {} bytes are refused", meta.len(), MAX_INPUT_BYTES)));
    }
    let text = std::fs::read_to_string(path).map_err(|e| IoError::new(path, e))?;
    Ok(match text.strip_prefix('\u{feff}') {
        Some(rest) => rest.to_string(),
        None => text,
    })
}

/// Writes `path` atomically: a temporary file beside it (named with the process id, so that
/// processes sharing a directory do not collide), then a rename. A reader never sees half a file.
pub fn write_atomic(path: &Path, text: &str) -> Result<(), IoError> {
    write_atomic_bytes(path, text.as_bytes())
}

/// [`write_atomic`] for bytes (PNG images). A failed write (a full disk, EFBIG) removes the
/// temporary file and leaves `path` as it was: never a truncated file under its final name.
pub fn write_atomic_bytes(path: &Path, bytes: &[u8]) -> Result<(), IoError> {
    let mut name = path.file_name().map(|n| n.to_os_string()).unwrap_or_default();
    name.push(format!(".tmp{}", std::process::id()));
    let tmp = path.with_file_name(name);
    crate::io::manifest::record(path)?;
    if let Err(e) = std::fs::write(&tmp, bytes) {
        let _ = std::fs::remove_file(&tmp);
        return Err(IoError::new(&tmp, e));
    }
    // a failed rename (the name taken by a directory, a vanished folder) removes it too
    std::fs::rename(&tmp, path).map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        IoError::new(path, e)
    })
}

/// The key of a checkpoint's checksum: the SHA-256 (hex) of the checkpoint's JSON text without it
/// (issue 38: a checkpoint changed or damaged after it was written is refused, not resumed).
pub const CHECKSUM_KEY: &str = "content_sha256";

fn sha256_hex(text: &str) -> String {
    use sha2::{Digest, Sha256};
    Sha256::digest(text.as_bytes()).iter().map(|b| format!("{b:02x}")).collect()
}

/// `json` (a JSON object's text) with its checksum appended as the last member [`CHECKSUM_KEY`].
pub fn seal(json: &str) -> String {
    let body = json.trim_end();
    match body.strip_suffix('}') {
        Some(open) if open.trim_end() != "{" => format!("{open},\"{CHECKSUM_KEY}\":\"{}\"}}", sha256_hex(body)),
        _ => body.to_string(),
    }
}

/// [`seal`] of a JSON value (an edited checkpoint: its old checksum dropped first).
pub fn seal_value(v: &serde_json::Value) -> String {
    let mut v = v.clone();
    if let Some(m) = v.as_object_mut() {
        m.remove(CHECKSUM_KEY);
    }
    seal(&v.to_string())
}

/// Writes a checkpoint's JSON text `json` atomically, sealed with its checksum ([`seal`]).
pub fn write_checkpoint_json(path: &Path, json: &str) -> Result<(), IoError> {
    write_atomic(path, &seal(json))
}

/// Reads a checkpoint written by [`write_checkpoint_json`] and returns its JSON text after checking
/// its checksum: a checkpoint without one, or whose content does not match it, is refused.
pub fn read_checkpoint_json(path: &Path) -> Result<String, IoError> {
    let text = read_input(path)?;
    let body = text.trim_end();
    let tail = format!(",\"{CHECKSUM_KEY}\":\"");
    let again = "sinterdem cannot continue it: run the case again (`--force`)";
    let Some((head, sum)) = body.rsplit_once(&tail) else {
        return Err(IoError::new(path, format!("has no checksum ({CHECKSUM_KEY}): written by an older sinterdem, or not by sinterdem; {again}")));
    };
    let sum = sum.strip_suffix("\"}").unwrap_or("");
    let json = format!("{head}}}");
    if sum.len() != 64 || sha256_hex(&json) != sum {
        return Err(IoError::new(
            path,
            format!("does not match its checksum ({CHECKSUM_KEY}): the checkpoint was changed or damaged after it was written; {again}"),
        ));
    }
    Ok(json)
}

/// Serde for `Vector3<f64>` as `[x, y, z]` (checkpoints; nalgebra's serde feature is off):
/// `#[serde(with = "crate::io::serde_v3")]` on a `Vector3<f64>` field.
pub mod serde_v3 {
    use nalgebra::Vector3;
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    pub fn serialize<S: Serializer>(v: &Vector3<f64>, s: S) -> Result<S::Ok, S::Error> {
        [v.x, v.y, v.z].serialize(s)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Vector3<f64>, D::Error> {
        let a = <[f64; 3]>::deserialize(d)?;
        Ok(Vector3::new(a[0], a[1], a[2]))
    }

    /// The same for `Vec<Vector3<f64>>`: `#[serde(with = "crate::io::serde_v3::vec")]`.
    pub mod vec {
        use nalgebra::Vector3;
        use serde::{Deserialize, Deserializer, Serialize, Serializer};

        pub fn serialize<S: Serializer>(v: &[Vector3<f64>], s: S) -> Result<S::Ok, S::Error> {
            v.iter().map(|x| [x.x, x.y, x.z]).collect::<Vec<_>>().serialize(s)
        }

        pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<Vector3<f64>>, D::Error> {
            Ok(Vec::<[f64; 3]>::deserialize(d)?.into_iter().map(|a| Vector3::new(a[0], a[1], a[2])).collect())
        }
    }
}

/// A text CSV field, quoted when it holds a comma, quote or line break (RFC 4180).
pub fn csv_text(s: &str) -> String {
    if s.contains([',', '"', '\n', '\r']) { format!("\"{}\"", s.replace('"', "\"\"")) } else { s.to_string() }
}

/// Writes pretty JSON atomically ([`write_atomic`]).
pub fn write_json(path: &Path, value: &serde_json::Value) -> Result<(), IoError> {
    let text = serde_json::to_string_pretty(value).map_err(|e| IoError::new(path, e))?;
    write_atomic(path, &(text + "\n"))
}

/// Whether a CSV column holds a count (written as an integer, read by pandas as `int64`): the
/// column names without a unit suffix that count things.
pub fn is_count_column(name: &str) -> bool {
    matches!(name, "contacts" | "steps" | "particles" | "rhs_evaluations" | "radiation_iterations" | "stage" | "particle_a" | "particle_b" | "id")
        || name.ends_with("_count")
}

/// One CSV field: counts as integers, everything else in full precision (`{:e}`); a non-finite
/// value is left empty (pandas reads NaN).
pub fn csv_field(value: f64, count: bool) -> String {
    if !value.is_finite() {
        String::new()
    } else if count {
        format!("{}", value.round() as i64)
    } else {
        format!("{value:e}")
    }
}

/// One column of a kind's series: its name as written in the CSV header (unit suffix included,
/// `time_s`), its SI unit as plots and HDF5 attributes show it (`"s"`, `"1"` for dimensionless),
/// and the getter that reads it from the kind's row state `S`. A kind keeps one list of columns
/// ([`header`], [`values`], [`label`] derive everything from it), so adding a column is one line.
pub struct Column<S: ?Sized> {
    pub name: &'static str,
    pub unit: &'static str,
    pub get: fn(&S) -> f64,
}

/// The CSV header of `columns`.
pub fn header<S: ?Sized>(columns: &[Column<S>]) -> Vec<&'static str> {
    columns.iter().map(|c| c.name).collect()
}

/// One row of `columns` read from `state`.
pub fn values<S: ?Sized>(columns: &[Column<S>], state: &S) -> Vec<f64> {
    columns.iter().map(|c| (c.get)(state)).collect()
}

/// The plot label of the column `name` of `columns`: `name [unit]` (None: no such column).
pub fn label<S: ?Sized>(columns: &[Column<S>], name: &str) -> Option<String> {
    columns.iter().find(|c| c.name == name).map(|c| if c.unit == "1" { c.name.to_string() } else { format!("{} [{}]", c.name, c.unit) })
}

#[cfg(test)]
mod column_tests {
    use super::*;
    struct Row {
        t: f64,
        n: usize,
    }
    const COLS: &[Column<Row>] = &[Column { name: "time_s", unit: "s", get: |r| r.t }, Column { name: "contacts", unit: "1", get: |r| r.n as f64 }];
    #[test]
    fn columns_give_header_row_and_labels_and_a_short_row_is_an_error() {
        assert_eq!(header(COLS), ["time_s", "contacts"]);
        assert_eq!(values(COLS, &Row { t: 2.5, n: 7 }), [2.5, 7.0]);
        assert_eq!(label(COLS, "time_s").as_deref(), Some("time_s [s]"));
        let dir = std::env::temp_dir().join(format!("sinterdem-columns-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let mut s = Series::create(&dir.join("s.csv"), &header(COLS)).unwrap();
        s.row(&values(COLS, &Row { t: 1.0, n: 3 })).unwrap();
        let e = s.row(&[1.0]).unwrap_err().to_string();
        assert!(e.contains("a row of 1 values for 2 columns"), "{e}");
        drop(s);
        assert_eq!(std::fs::read_to_string(dir.join("s.csv")).unwrap(), "time_s,contacts\n1e0,3\n");
        let _ = std::fs::remove_dir_all(&dir);
    }
}

/// A CSV time series written row by row (flushed at every row, so an interrupted run keeps its rows).
///
/// Every CSV the project writes has one plain header line (no comment line before it, so
/// `pandas.read_csv(path)` reads it unchanged), column names that carry their unit (`time_s`,
/// `temperature_K`; no suffix = dimensionless) and counts written as integers ([`is_count_column`]).
pub struct Series {
    path: PathBuf,
    file: std::io::BufWriter<std::fs::File>,
    counts: Vec<bool>,
}

impl Series {
    /// Creates the file and writes the header. Column names carry their unit, e.g. `time_s`.
    pub fn create(path: &Path, header: &[&str]) -> Result<Self, IoError> {
        crate::io::manifest::record(path)?;
        let f = std::fs::File::create(path).map_err(|e| IoError::new(path, e))?;
        let counts = header.iter().map(|h| is_count_column(h)).collect();
        let mut s = Series { path: path.to_path_buf(), file: std::io::BufWriter::new(f), counts };
        writeln!(s.file, "{}", header.join(",")).map_err(|e| IoError::new(path, e))?;
        Ok(s)
    }

    /// Reopens a series for appending after its first `keep_lines` lines (header included), dropping
    /// the rows written after a checkpoint.
    pub fn resume(path: &Path, keep_lines: usize, columns: usize) -> Result<Self, IoError> {
        let text = std::fs::read_to_string(path).map_err(|e| IoError::new(path, e))?;
        let kept: Vec<&str> = text.lines().take(keep_lines).collect();
        if kept.len() != keep_lines {
            return Err(IoError::new(path, format!("has {} lines, the checkpoint expects at least {keep_lines}", kept.len())));
        }
        let counts: Vec<bool> = match kept.first() {
            Some(h) if h.split(',').count() == columns => h.split(',').map(is_count_column).collect(),
            _ => vec![false; columns],
        };
        let mut body = kept.join("\n");
        body.push('\n');
        // temporary file + rename: a resume killed here leaves the old series or the cut one,
        // never a truncated file that no later resume accepts (docs/outputs.md "Guarantees")
        write_atomic(path, &body)?;
        let f = std::fs::OpenOptions::new().append(true).open(path).map_err(|e| IoError::new(path, e))?;
        Ok(Series { path: path.to_path_buf(), file: std::io::BufWriter::new(f), counts })
    }

    /// Appends one row (full precision; counts as integers). A row whose length is not the
    /// header's is an error (the columns are kept aligned by name, [`Column`], never by position).
    pub fn row(&mut self, values: &[f64]) -> Result<(), IoError> {
        if values.len() != self.counts.len() {
            return Err(IoError::new(&self.path, format!("internal: a row of {} values for {} columns", values.len(), self.counts.len())));
        }
        let line: Vec<String> = values.iter().zip(&self.counts).map(|(&v, &c)| csv_field(v, c)).collect();
        writeln!(self.file, "{}", line.join(",")).map_err(|e| IoError::new(&self.path, e))?;
        self.file.flush().map_err(|e| IoError::new(&self.path, e))
    }
}

/// What a run writes once into its HDF5 file (`/parameters`): the case as run and the material data.
#[derive(Debug, Clone, Default)]
pub struct Parameters {
    /// The resolved case (overrides applied), TOML.
    pub case_toml: String,
    /// The material data the run used, JSON.
    pub materials_json: String,
}

/// One snapshot of a packing: particles as points, contacts as lines.
///
/// Array names carry their unit (`neck_radius_m`, no suffix = dimensionless) and mean the same in
/// every kind (docs/outputs.md). Particle ids and the coordination are derived by the writers.
#[derive(Debug, Clone, Default)]
pub struct Snapshot<'a> {
    /// Simulated time [s].
    pub time: f64,
    /// Step number of the run at this snapshot.
    pub step: u64,
    /// Particle centres [m].
    pub position: &'a [nalgebra::Vector3<f64>],
    /// Particle radii [m].
    pub radius: &'a [f64],
    /// Particle temperatures [K].
    pub temperature: &'a [f64],
    /// Contact pairs (particle indices).
    pub contacts: &'a [[u32; 2]],
    /// Contact data arrays, each one value per contact: (name with unit, values).
    pub contact_data: Vec<(&'a str, &'a [f64])>,
    /// Extra particle data arrays: (name with unit, values).
    pub particle_data: Vec<(&'a str, &'a [f64])>,
    /// Particle vector arrays (3 components): (name with unit, values), e.g. `displacement_m`.
    pub particle_vectors: Vec<(&'a str, &'a [nalgebra::Vector3<f64>])>,
    /// Run metadata for the HDF5 file (written once, with the first snapshot that carries it).
    pub parameters: Option<Parameters>,
}

/// Writes snapshots as VTU (with PVD indexes) and HDF5 as configured.
pub struct SnapshotWriter {
    dir: PathBuf,
    vtu: Option<vtu::PvdIndex>,
    h5: Option<hdf5::H5Writer>,
    count: usize,
}

/// An opened HDF5 writer, or `None` with the log told that HDF5 output is off in this build.
fn h5_or_off(r: Result<hdf5::H5Writer, hdf5::H5Error>, log: &mut dyn FnMut(&str)) -> Result<Option<hdf5::H5Writer>, IoError> {
    match r {
        Ok(w) => Ok(Some(w)),
        Err(hdf5::H5Error::Disabled) => {
            log(hdf5::DISABLED_MESSAGE);
            Ok(None)
        }
        Err(hdf5::H5Error::Io(e)) => Err(e),
    }
}

impl SnapshotWriter {
    /// `vtu`, `h5`: which formats. HDF5 without the `h5` build feature logs a clear message once
    /// and is skipped.
    pub fn new(dir: &Path, vtu: bool, h5: bool, log: &mut dyn FnMut(&str)) -> Result<Self, IoError> {
        let vtu = if vtu { Some(vtu::PvdIndex::new(dir)) } else { None };
        let h5 = if h5 { h5_or_off(hdf5::H5Writer::create(&dir.join("sinterdem.h5")), log)? } else { None };
        Ok(SnapshotWriter { dir: dir.to_path_buf(), vtu, h5, count: 0 })
    }

    pub fn write(&mut self, s: &Snapshot) -> Result<(), IoError> {
        if let Some(v) = &mut self.vtu {
            v.write(&self.dir, self.count, s)?;
        }
        if let Some(h) = &mut self.h5 {
            h.write(self.count, s)?;
        }
        self.count += 1;
        Ok(())
    }

    /// Number of snapshots written.
    pub fn count(&self) -> usize {
        self.count
    }

    /// The VTU index entries (for checkpoints).
    pub fn vtu_entries(&self) -> Vec<(f64, String, String)> {
        self.vtu.as_ref().map(|v| v.entries().to_vec()).unwrap_or_default()
    }

    /// Continues after a checkpoint that had written `count` snapshots.
    pub fn resume(dir: &Path, vtu: bool, h5: bool, count: usize, entries: Vec<(f64, String, String)>, log: &mut dyn FnMut(&str)) -> Result<Self, IoError> {
        let vtu = if vtu { Some(vtu::PvdIndex::with_entries(entries)) } else { None };
        let h5 = if h5 { h5_or_off(hdf5::H5Writer::reopen(&dir.join("sinterdem.h5"), count), log)? } else { None };
        if let Some(note) = h5.as_ref().and_then(|w| w.note.as_deref()) {
            log(note);
        }
        Ok(SnapshotWriter { dir: dir.to_path_buf(), vtu, h5, count })
    }

    pub fn hdf5_enabled(&self) -> bool {
        self.h5.is_some()
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn csv_text_quotes_commas_quotes_and_line_breaks() {
        assert_eq!(super::csv_text("a,b"), "\"a,b\"");
        assert_eq!(super::csv_text("say \"x\""), "\"say \"\"x\"\"\"");
        assert_eq!(super::csv_text("two\nlines"), "\"two\nlines\"");
        assert_eq!(super::csv_text("plain"), "plain");
    }
}
