//! Measured data of a calibration: one row per experiment
//! (`id,diameter_m,schedule,neck_ratio,neck_ratio_sigma,shrinkage,shrinkage_sigma`) and an optional
//! time-series file (`id,time_s,neck_ratio,neck_ratio_sigma,shrinkage,shrinkage_sigma`).
//!
//! Both are CSV with a header row (columns in any order, exactly these names), RFC 4180 quoting (the
//! schedule contains commas: `"start 793 K, heat 20 K/min to 1203 K, hold 0 min, cool 20 K/min to
//! 313 K"`) and `#` comment lines. Either measurement of a row may be empty; a given value needs its
//! sigma (one standard deviation, same unit). Every error names the file, line and column.

use super::lookup;
use crate::error::{ConfigError, Error};
use crate::profile::Profile;
use std::collections::HashMap;
use std::path::Path;

/// Columns of the experiment file, in the documented order.
pub const DATA_COLUMNS: [&str; 7] = ["id", "diameter_m", "schedule", "neck_ratio", "neck_ratio_sigma", "shrinkage", "shrinkage_sigma"];
/// Columns of the time-series file.
pub const SERIES_COLUMNS: [&str; 6] = ["id", "time_s", "neck_ratio", "neck_ratio_sigma", "shrinkage", "shrinkage_sigma"];

/// One measured value and its standard deviation (same unit).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Measured {
    pub value: f64,
    pub sigma: f64,
}

/// Neck ratio y1/R [1] and shrinkage ΔL/L0 [1] measured at one time; either may be missing.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Observation {
    pub neck_ratio: Option<Measured>,
    pub shrinkage: Option<Measured>,
}

impl Observation {
    /// Number of measured values (0, 1 or 2).
    pub fn count(&self) -> usize {
        self.neck_ratio.is_some() as usize + self.shrinkage.is_some() as usize
    }
}

/// A time-series point: an observation at time `time` [s] of the experiment's schedule.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SeriesPoint {
    /// Time since the start of the schedule [s].
    pub time: f64,
    pub observation: Observation,
}

/// One experiment: two spheres of diameter `diameter` [m] under `profile`, observed at its end and,
/// optionally, at series times.
#[derive(Debug, Clone, PartialEq)]
pub struct Experiment {
    pub id: String,
    /// Mean particle diameter [m].
    pub diameter: f64,
    /// The schedule as written in the file.
    pub schedule: String,
    pub profile: Profile,
    /// Observation at the end of the schedule.
    pub end: Observation,
    /// Observations during the schedule, in increasing time.
    pub series: Vec<SeriesPoint>,
}

impl Experiment {
    /// Number of measured values of this experiment (residuals it contributes).
    pub fn count(&self) -> usize {
        self.end.count() + self.series.iter().map(|p| p.observation.count()).sum::<usize>()
    }
}

struct Table {
    file: String,
    columns: HashMap<String, usize>,
    rows: Vec<(u64, csv::StringRecord)>,
}

impl Table {
    fn cell<'a>(&self, rec: &'a csv::StringRecord, name: &str) -> &'a str {
        rec.get(self.columns[name]).unwrap_or("").trim()
    }
    fn at(&self, line: u64, name: &str) -> String {
        format!("{} line {line}, column {} ({name})", self.file, self.columns[name] + 1)
    }
    fn err(&self, line: u64, name: &str, why: impl std::fmt::Display) -> ConfigError {
        ConfigError::invalid(format!("{}: {why}", self.at(line, name)))
    }
    /// A number in the range of `data.<name>` (or of `range_key`), or None if the cell is empty.
    fn number(&self, rec: &csv::StringRecord, line: u64, name: &str, range_key: &str) -> Result<Option<f64>, ConfigError> {
        let s = self.cell(rec, name);
        if s.is_empty() {
            return Ok(None);
        }
        let v: f64 = s.parse().map_err(|_| self.err(line, name, format!("\"{s}\" is not a number")))?;
        let r = lookup(range_key).ok_or_else(|| ConfigError::invalid(format!("internal: no range for {range_key}")))?;
        r.check(&self.at(line, name), v)?;
        Ok(Some(v))
    }
    fn measured(&self, rec: &csv::StringRecord, line: u64, what: &str) -> Result<Option<Measured>, ConfigError> {
        let sname = format!("{what}_sigma");
        let v = self.number(rec, line, what, &format!("data.{what}"))?;
        let s = self.number(rec, line, &sname, &format!("data.{sname}"))?;
        match (v, s) {
            (Some(value), Some(sigma)) => Ok(Some(Measured { value, sigma })),
            (None, None) => Ok(None),
            (Some(_), None) => Err(self.err(line, &sname, format!("{what} is given, so its sigma (one standard deviation) is needed"))),
            (None, Some(_)) => Err(self.err(line, what, format!("empty, but {sname} is given: give both or neither"))),
        }
    }
}

fn read_table(path: &Path, expected: &[&str]) -> Result<Table, Error> {
    let file = path.display().to_string();
    let text = crate::io::read_input(path)?;
    let mut rd = csv::ReaderBuilder::new().has_headers(true).comment(Some(b'#')).flexible(false).trim(csv::Trim::All).from_reader(text.as_bytes());
    let csv_err = |e: csv::Error| -> ConfigError {
        let line = e.position().map(|p| format!(" line {}", p.line())).unwrap_or_default();
        let msg = match e.kind() {
            csv::ErrorKind::UnequalLengths { expected_len, len, .. } => format!("{len} fields, the header has {expected_len}"),
            _ => e.to_string(),
        };
        ConfigError::invalid(format!("{file}{line}: {msg}"))
    };
    let header = rd.headers().map_err(csv_err)?.clone();
    let header_line = header.position().map(|p| p.line()).unwrap_or(1).max(1);
    let mut columns = HashMap::new();
    for (i, h) in header.iter().enumerate() {
        let h = h.trim();
        if !expected.contains(&h) {
            return Err(ConfigError::invalid(format!(
                "{file} line {header_line}, column {} (\"{h}\"): unknown column; the header must name exactly: {}",
                i + 1,
                expected.join(",")
            ))
            .into());
        }
        if columns.insert(h.to_string(), i).is_some() {
            return Err(ConfigError::invalid(format!("{file} line {header_line}, column {} (\"{h}\"): duplicate column", i + 1)).into());
        }
    }
    if let Some(m) = expected.iter().find(|c| !columns.contains_key(**c)) {
        return Err(ConfigError::invalid(format!(
            "{file} line {header_line}: column \"{m}\" is missing; the header must name exactly: {}",
            expected.join(",")
        ))
        .into());
    }
    let mut rows = Vec::new();
    for rec in rd.records() {
        let rec = rec.map_err(csv_err)?;
        let line = rec.position().map(|p| p.line()).unwrap_or(0);
        rows.push((line, rec));
    }
    Ok(Table { file, columns, rows })
}

/// Reads the experiment file.
pub fn read_experiments(path: &Path) -> Result<Vec<Experiment>, Error> {
    let t = read_table(path, &DATA_COLUMNS)?;
    let mut out: Vec<Experiment> = Vec::new();
    // ids seen so far: a hash set keeps the file's reading linear in its rows
    let mut seen: std::collections::HashSet<String> = std::collections::HashSet::new();
    for (line, rec) in &t.rows {
        let line = *line;
        let id = t.cell(rec, "id");
        if id.is_empty() {
            return Err(t.err(line, "id", "empty id").into());
        }
        if !seen.insert(id.to_string()) {
            return Err(t.err(line, "id", format!("id \"{id}\" appears twice")).into());
        }
        let diameter = t
            .number(rec, line, "diameter_m", "data.diameter_m")?
            .ok_or_else(|| t.err(line, "diameter_m", "empty: the mean particle diameter [m] is needed"))?;
        let schedule = t.cell(rec, "schedule").to_string();
        if schedule.is_empty() {
            return Err(t.err(line, "schedule", "empty schedule").into());
        }
        let profile = Profile::from_schedule(&schedule).map_err(|e| t.err(line, "schedule", e))?;
        if !(profile.duration() > 0.0) {
            return Err(t.err(line, "schedule", "the schedule has zero length (no heat, cool or hold step)").into());
        }
        let end = Observation { neck_ratio: t.measured(rec, line, "neck_ratio")?, shrinkage: t.measured(rec, line, "shrinkage")? };
        out.push(Experiment { id: id.to_string(), diameter, schedule, profile, end, series: Vec::new() });
    }
    if out.is_empty() {
        return Err(ConfigError::invalid(format!("{}: no experiments (only a header)", t.file)).into());
    }
    Ok(out)
}

/// Reads the time-series file and attaches its points to `experiments` (by id).
pub fn read_series(path: &Path, experiments: &mut [Experiment]) -> Result<(), Error> {
    let t = read_table(path, &SERIES_COLUMNS)?;
    // experiment index by id and the times of each experiment's points: linear in the rows
    let index: std::collections::HashMap<String, usize> = experiments.iter().enumerate().map(|(i, e)| (e.id.clone(), i)).collect();
    let mut times: Vec<std::collections::HashSet<u64>> = experiments.iter().map(|e| e.series.iter().map(|p| p.time.to_bits()).collect()).collect();
    for (line, rec) in &t.rows {
        let line = *line;
        let id = t.cell(rec, "id");
        let Some(&ei) = index.get(id) else {
            return Err(t.err(line, "id", format!("id \"{id}\" is not an experiment of the data file")).into());
        };
        let e = &mut experiments[ei];
        let time = t.number(rec, line, "time_s", "data.time_s")?.ok_or_else(|| t.err(line, "time_s", "empty time"))?;
        if time > e.profile.duration() {
            return Err(t.err(line, "time_s", format!("{time} s is after the end of experiment {id}'s schedule ({} s)", e.profile.duration())).into());
        }
        // (+0.0 for −0.0: one instant)
        if !times[ei].insert((time + 0.0).to_bits()) {
            return Err(t.err(line, "time_s", format!("experiment {id} already has a point at {time} s")).into());
        }
        let observation = Observation { neck_ratio: t.measured(rec, line, "neck_ratio")?, shrinkage: t.measured(rec, line, "shrinkage")? };
        if observation.count() == 0 {
            return Err(t.err(line, "neck_ratio", "neither neck_ratio nor shrinkage is given").into());
        }
        e.series.push(SeriesPoint { time, observation });
    }
    for e in experiments.iter_mut() {
        e.series.sort_by(|a, b| a.time.total_cmp(&b.time));
    }
    Ok(())
}

/// Checks that every experiment contributes at least one value.
pub fn check_counts(experiments: &[Experiment], data_file: &str) -> Result<(), ConfigError> {
    for e in experiments {
        if e.count() == 0 {
            return Err(ConfigError::invalid(format!("{data_file}: experiment {} has neither neck_ratio nor shrinkage (and no series points)", e.id)));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(name: &str, text: &str) -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!("sinterdem-calib-data-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join(name);
        std::fs::write(&p, text).unwrap();
        p
    }

    const HEAD: &str = "id,diameter_m,schedule,neck_ratio,neck_ratio_sigma,shrinkage,shrinkage_sigma\n";

    #[test]
    fn reads_quoted_schedules_empty_values_and_comments() {
        let p = write(
            "ok.csv",
            &format!(
                "# comment\n{HEAD}E1,65e-6,\"start 793 K, heat 20 K/min to 1203 K, hold 0 min, cool 20 K/min to 313 K\",0.48,0.01,,\nE2,66e-6,\"start 793 K, heat 20 K/min to 1373 K, hold 30 min\",,,0.014,0.001\n"
            ),
        );
        let e = read_experiments(&p).unwrap();
        assert_eq!(e.len(), 2);
        assert_eq!(e[0].end.neck_ratio, Some(Measured { value: 0.48, sigma: 0.01 }));
        assert_eq!(e[0].end.shrinkage, None);
        assert_eq!(e[0].profile.breakpoints().len(), 3);
        assert_eq!(e[1].end.count(), 1);
        let s = write("s.csv", "id,time_s,neck_ratio,neck_ratio_sigma,shrinkage,shrinkage_sigma\nE2,600,,,0.001,0.0002\nE2,300,0.3,0.01,,\n");
        let mut e = e;
        read_series(&s, &mut e).unwrap();
        assert_eq!(e[1].series.len(), 2);
        assert_eq!(e[1].series[0].time, 300.0);
        assert_eq!(e[1].count(), 3);
    }

    #[test]
    fn bad_rows_name_file_line_and_column() {
        let sched = "\"start 793 K, heat 20 K/min to 1203 K\"";
        let cases = [
            (format!("{HEAD}E1,65e-6,{sched},0.48,0.01,,\nE2,abc,{sched},0.5,0.01,,\n"), "line 3, column 2 (diameter_m)", "not a number"),
            (format!("{HEAD}E1,65e-6,{sched},1.5,0.01,,\n"), "line 2, column 4 (neck_ratio)", "out of range"),
            (format!("{HEAD}E1,65e-6,{sched},0.5,,,\n"), "line 2, column 5 (neck_ratio_sigma)", "sigma"),
            (format!("{HEAD}E1,65e-6,\"start 793 K, heat 20 furlongs to 1203 K\",0.5,0.01,,\n"), "line 2, column 3 (schedule)", "furlongs"),
            (format!("{HEAD}E1,65e-6,{sched},0.5,0.01\n"), "line 2", "fields"),
            (format!("{HEAD}E1,65e-6,{sched},0.5,0.01,,\nE1,65e-6,{sched},0.5,0.01,,\n"), "line 3, column 1 (id)", "twice"),
            ("id,diameter,schedule,neck_ratio,neck_ratio_sigma,shrinkage,shrinkage_sigma\n".to_string(), "line 1, column 2", "unknown column"),
        ];
        for (i, (text, at, why)) in cases.iter().enumerate() {
            let p = write(&format!("bad{i}.csv"), text);
            let e = read_experiments(&p).unwrap_err().to_string();
            assert!(e.contains(&format!("bad{i}.csv")) && e.contains(at) && e.contains(why), "case {i}: {e}");
        }
    }

    #[test]
    fn large_files_keep_every_duplicate_check_with_hashed_ids_and_times() {
        // 20 000 experiments and 60 000 series points; the duplicate sits at the far end
        let mut data = HEAD.to_string();
        for i in 0..20_000 {
            data.push_str(&format!("E{i},65e-6,\"start 793 K, heat 20 K/min to 1203 K\",0.48,0.01,,\n"));
        }
        let e = read_experiments(&write("big.csv", &data)).unwrap();
        assert_eq!(e.len(), 20_000);
        data.push_str("E0,65e-6,\"start 793 K, heat 20 K/min to 1203 K\",0.48,0.01,,\n");
        let err = read_experiments(&write("big-dup.csv", &data)).unwrap_err().to_string();
        assert!(err.contains("line 20002") && err.contains("\"E0\" appears twice"), "{err}");

        let mut series = "id,time_s,neck_ratio,neck_ratio_sigma,shrinkage,shrinkage_sigma\n".to_string();
        for i in 0..20_000 {
            for t in [60.0, 120.0, 180.0] {
                series.push_str(&format!("E{i},{t},0.3,0.01,,\n"));
            }
        }
        let mut ex = e.clone();
        read_series(&write("big-series.csv", &series), &mut ex).unwrap();
        assert!(ex.iter().all(|x| x.series.len() == 3 && x.series[2].time == 180.0));
        series.push_str("E19999,120.0,0.3,0.01,,\n");
        let mut ex = e.clone();
        let err = read_series(&write("big-series-dup.csv", &series), &mut ex).unwrap_err().to_string();
        assert!(err.contains("line 60002") && err.contains("already has a point at 120 s"), "{err}");
    }
}
