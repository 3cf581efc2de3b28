//! Heating profiles: prescribed temperature histories T(t) [K] as piecewise-linear ramps and holds.
//!
//! A profile is stored as breakpoints `(t_k, T_k)` with increasing times (two equal times make a
//! jump, continuous from the left); between them T is
//! linear, before the first it is `T_0`, after the last it is held. Three input forms:
//! - a schedule string: `"start 293 K, heat 20 K/min to 1203 K, hold 30 min, cool 20 K/min to 313 K"`
//!   (rates in K/s, K/min or K/h; durations in s, min or h; temperatures in K or °C written `C`),
//! - a table of `[t, T]` pairs,
//! - a constant.
//!
//! The breakpoints are the profile's kinks: integrators split their substeps there (docs/diffusion7.md §3).

use crate::error::ConfigError;
use crate::units::ZERO_CELSIUS;
use serde::{Deserialize, Serialize};

/// A piecewise-linear temperature history.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Profile {
    /// Breakpoint times [s], increasing (a pair of equal times is a jump).
    times: Vec<f64>,
    /// Temperatures at the breakpoints [K].
    temps: Vec<f64>,
}

/// How a profile is written in a case file (exactly one of the three keys).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProfileSpec {
    /// Schedule string, e.g. `"start 293 K, heat 20 K/min to 1203 K, hold 30 min"`.
    pub schedule: Option<String>,
    /// Table of `[time s, temperature K]` rows, times increasing (two equal times: a jump).
    pub table: Option<Vec<[f64; 2]>>,
    /// Constant temperature [K].
    pub constant: Option<f64>,
}

/// Lowest and highest temperature any profile may reach [K].
pub const T_MIN: f64 = 1.0;
pub const T_MAX: f64 = 1.0e4;

fn check_temperature(key: &str, t: f64) -> Result<f64, ConfigError> {
    if !(T_MIN..=T_MAX).contains(&t) || !t.is_finite() {
        return Err(ConfigError::OutOfRange { key: key.to_string(), value: t, range: format!("[{T_MIN}, {T_MAX}]"), unit: "K".into() });
    }
    Ok(t)
}

impl Profile {
    /// A constant temperature `t` [K].
    pub fn constant(t: f64) -> Result<Self, ConfigError> {
        check_temperature("profile.constant", t)?;
        Ok(Profile { times: vec![0.0], temps: vec![t] })
    }

    /// From `(time s, temperature K)` rows with increasing times; two rows with the same time
    /// make a jump (the first row's value at that time, the second's after it), except at the
    /// first row (a jump there would be a different start value: give that one).
    pub fn from_table(rows: &[[f64; 2]]) -> Result<Self, ConfigError> {
        if rows.is_empty() {
            return Err(ConfigError::invalid("profile.table: needs at least one [time, temperature] row"));
        }
        let mut times = Vec::with_capacity(rows.len());
        let mut temps = Vec::with_capacity(rows.len());
        for (k, r) in rows.iter().enumerate() {
            if !r[0].is_finite() || r[0] < 0.0 {
                return Err(ConfigError::OutOfRange { key: format!("profile.table[{k}].time"), value: r[0], range: "[0, inf)".into(), unit: "s".into() });
            }
            if let Some(&last) = times.last()
                && (r[0] < last || r[0] == last && (k < 2 || times[k - 2] == last))
            {
                return Err(ConfigError::invalid(format!(
                    "profile.table[{k}]: time {} s is not after the previous row's {} s (two rows with the same time make a jump, but not at the first row; three may not)",
                    r[0], last
                )));
            }
            times.push(r[0]);
            temps.push(check_temperature(&format!("profile.table[{k}].temperature"), r[1])?);
        }
        Ok(Profile { times, temps })
    }

    /// Parses a schedule string (see the module docs).
    pub fn from_schedule(s: &str) -> Result<Self, ConfigError> {
        let mut times = vec![0.0];
        let mut temps: Vec<f64> = Vec::new();
        for (k, raw) in s.split(',').map(str::trim).filter(|x| !x.is_empty()).enumerate() {
            let words: Vec<&str> = raw.split_whitespace().collect();
            let bad = |why: &str| ConfigError::invalid(format!("profile.schedule: cannot read \"{raw}\": {why}"));
            match words.first().copied() {
                Some("start") if k == 0 => {
                    let t = parse_temperature(&words[1..]).map_err(|e| bad(&e))?;
                    temps.push(check_temperature("profile.schedule start", t)?);
                }
                Some("heat") | Some("cool") => {
                    let Some(&t0) = temps.last() else {
                        return Err(bad("the schedule must begin with \"start T K\""));
                    };
                    // heat|cool RATE UNIT to TEMP UNIT
                    let to = words.iter().position(|w| *w == "to").ok_or_else(|| bad("expected \"... to T K\""))?;
                    let rate = parse_rate(&words[1..to]).map_err(|e| bad(&e))?.abs();
                    if !(rate > 0.0 && rate.is_finite()) {
                        return Err(bad("the rate must be positive"));
                    }
                    let t1 = check_temperature("profile.schedule target", parse_temperature(&words[to + 1..]).map_err(|e| bad(&e))?)?;
                    let heating = words[0] == "heat";
                    if heating && t1 <= t0 || !heating && t1 >= t0 {
                        return Err(bad(&format!("{} from {t0} K to {t1} K goes the wrong way", if heating { "heating" } else { "cooling" })));
                    }
                    let dt = (t1 - t0).abs() / rate;
                    times.push(times.last().unwrap() + dt);
                    temps.push(t1);
                }
                Some("hold") => {
                    let Some(&t0) = temps.last() else {
                        return Err(bad("the schedule must begin with \"start T K\""));
                    };
                    let d = parse_duration(&words[1..]).map_err(|e| bad(&e))?;
                    if !(d >= 0.0 && d.is_finite()) {
                        return Err(bad("the hold time must be zero or positive"));
                    }
                    // `hold 0 min` (lab tables list zero holds) adds no breakpoint
                    if d > 0.0 {
                        times.push(times.last().unwrap() + d);
                        temps.push(t0);
                    }
                }
                _ => return Err(bad("expected start, heat, cool or hold")),
            }
        }
        if temps.is_empty() {
            return Err(ConfigError::invalid("profile.schedule: empty schedule"));
        }
        times.truncate(temps.len());
        Ok(Profile { times, temps })
    }

    /// Builds a profile from its case-file form.
    pub fn from_spec(spec: &ProfileSpec, key: &str) -> Result<Self, ConfigError> {
        let n = spec.schedule.is_some() as u8 + spec.table.is_some() as u8 + spec.constant.is_some() as u8;
        if n != 1 {
            return Err(ConfigError::inconsistent(key, "give exactly one of schedule, table, constant"));
        }
        let r = if let Some(s) = &spec.schedule {
            Self::from_schedule(s)
        } else if let Some(t) = &spec.table {
            Self::from_table(t)
        } else {
            Self::constant(spec.constant.unwrap())
        };
        r.map_err(|e| match e {
            // the inner keys start with "profile." (a profile alone); `key` already ends there
            ConfigError::OutOfRange { key: k, value, range, unit } => {
                ConfigError::OutOfRange { key: format!("{key}.{}", k.strip_prefix("profile.").unwrap_or(&k)), value, range, unit }
            }
            ConfigError::Invalid(m) => ConfigError::Invalid(format!("{key}.{}", m.strip_prefix("profile.").unwrap_or(&m))),
            other => other,
        })
    }

    /// Temperature at time `t` [s] → [K] (eq.: linear interpolation between breakpoints, held outside).
    ///
    /// At a jump (two rows with the same time) the profile is continuous from the left: at the
    /// jump's time it has the first row's value, after it the second's.
    pub fn temperature(&self, t: f64) -> f64 {
        let n = self.times.len();
        if t <= self.times[0] {
            return self.temps[0];
        }
        if t >= self.times[n - 1] {
            return if n >= 2 && t == self.times[n - 1] && self.times[n - 2] == t { self.temps[n - 2] } else { self.temps[n - 1] };
        }
        let k = self.times.partition_point(|&x| x <= t); // times[k-1] <= t < times[k]
        if k >= 2 && self.times[k - 2] == t {
            return self.temps[k - 2];
        }
        let (t0, t1) = (self.times[k - 1], self.times[k]);
        let w = (t - t0) / (t1 - t0);
        self.temps[k - 1] + w * (self.temps[k] - self.temps[k - 1])
    }

    /// dT/dt at time `t` [K/s] (right derivative).
    pub fn rate(&self, t: f64) -> f64 {
        let n = self.times.len();
        if t < self.times[0] || t >= self.times[n - 1] {
            return 0.0;
        }
        let k = self.times.partition_point(|&x| x <= t);
        (self.temps[k] - self.temps[k - 1]) / (self.times[k] - self.times[k - 1])
    }

    /// Breakpoint times [s] (kinks of T(t)).
    pub fn breakpoints(&self) -> &[f64] {
        &self.times
    }

    /// Breakpoint temperatures [K].
    pub fn breakpoint_temperatures(&self) -> &[f64] {
        &self.temps
    }

    /// Time of the last breakpoint [s]: after it the temperature is held.
    pub fn duration(&self) -> f64 {
        *self.times.last().unwrap()
    }

    /// The first time in `[0, end]` [s] at which the temperature reaches `level` [K] (None: it
    /// stays below): exact on the piecewise-linear history.
    pub fn first_reaching(&self, level: f64, end: f64) -> Option<f64> {
        if self.temperature(0.0) >= level {
            return Some(0.0);
        }
        for k in 1..self.times.len() {
            let (t0, t1) = (self.times[k - 1], self.times[k]);
            if t0 > end {
                break;
            }
            let (a, b) = (self.temps[k - 1], self.temps[k]);
            if b >= level && a < level {
                let t = t0 + (level - a) / (b - a) * (t1 - t0);
                return (t <= end).then_some(t.max(0.0));
            }
        }
        None
    }

    /// Highest and lowest temperature of the profile [K].
    pub fn range(&self) -> (f64, f64) {
        let lo = self.temps.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = self.temps.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        (lo, hi)
    }

    /// Whether the profile is constant in time.
    pub fn is_constant(&self) -> bool {
        self.temps.iter().all(|&t| t == self.temps[0])
    }

    /// Times in `(t0, t1)` where the profile has a kink or crosses `t_cross` [K]; sorted.
    pub fn split_points(&self, t0: f64, t1: f64, t_cross: Option<f64>) -> Vec<f64> {
        let mut out: Vec<f64> = self.times.iter().copied().filter(|&t| t > t0 && t < t1).collect();
        if let Some(tc) = t_cross {
            for k in 1..self.times.len() {
                let (a, b) = (self.temps[k - 1], self.temps[k]);
                if (a - tc) * (b - tc) < 0.0 {
                    let t = self.times[k - 1] + (tc - a) / (b - a) * (self.times[k] - self.times[k - 1]);
                    if t > t0 && t < t1 {
                        out.push(t);
                    }
                }
            }
        }
        out.sort_by(f64::total_cmp);
        out.dedup();
        out
    }

    /// This profile up to time `t` [s], then `temperature` [K] held from `t` on (a jump at `t`
    /// unless `t` is 0): what `set_furnace_temperature` makes of a furnace profile. The same
    /// profile is written in a case as the table [`Profile::rows`] of the result.
    pub fn hold_from(&self, t: f64, temperature: f64) -> Result<Profile, ConfigError> {
        check_temperature("furnace temperature", temperature)?;
        if !(t.is_finite() && t > 0.0) {
            return Profile::constant(temperature);
        }
        let k = self.times.partition_point(|&x| x < t);
        let mut times = self.times[..k].to_vec();
        let mut temps = self.temps[..k].to_vec();
        if k == 0 {
            // no row before t: the history was its first value until then (a table's first row)
            times.push(0.0);
            temps.push(self.temps[0]);
        }
        times.extend([t, t]);
        temps.extend([self.temperature(t), temperature]);
        Ok(Profile { times, temps })
    }

    /// The profile as `[time s, temperature K]` rows (`table = …` in a case file).
    pub fn rows(&self) -> Vec<[f64; 2]> {
        self.times.iter().zip(&self.temps).map(|(&a, &b)| [a, b]).collect()
    }
}

fn parse_number(w: &str) -> Result<f64, String> {
    w.parse::<f64>().map_err(|_| format!("\"{w}\" is not a number"))
}

/// `["1203", "K"]`, `["930", "C"]`, `["1203K"]`.
fn parse_temperature(words: &[&str]) -> Result<f64, String> {
    let joined: String = words.concat();
    let (num, unit) = split_unit(&joined);
    let v = parse_number(num)?;
    match unit {
        "K" | "" => Ok(v),
        "C" | "°C" | "degC" => Ok(v + ZERO_CELSIUS),
        u => Err(format!("unknown temperature unit \"{u}\" (K or C)")),
    }
}

/// `["20", "K/min"]` → K/s.
fn parse_rate(words: &[&str]) -> Result<f64, String> {
    let joined: String = words.concat();
    let (num, unit) = split_unit(&joined);
    let v = parse_number(num)?;
    match unit {
        "K/s" | "C/s" => Ok(v),
        "K/min" | "C/min" => Ok(v / 60.0),
        "K/h" | "C/h" => Ok(v / 3600.0),
        u => Err(format!("unknown rate unit \"{u}\" (K/s, K/min, K/h)")),
    }
}

/// `["30", "min"]` → s.
fn parse_duration(words: &[&str]) -> Result<f64, String> {
    let joined: String = words.concat();
    let (num, unit) = split_unit(&joined);
    let v = parse_number(num)?;
    match unit {
        "s" | "" => Ok(v),
        "min" => Ok(v * 60.0),
        "h" => Ok(v * 3600.0),
        u => Err(format!("unknown duration unit \"{u}\" (s, min, h)")),
    }
}

fn split_unit(s: &str) -> (&str, &str) {
    let i = s
        .char_indices()
        .find(|&(i, c)| {
            !(c.is_ascii_digit()
                || c == '.'
                || c == '-'
                || c == '+'
                || ((c == 'e' || c == 'E') && i > 0 && s[i + 1..].starts_with(|d: char| d.is_ascii_digit() || d == '-')))
        })
        .map(|(i, _)| i)
        .unwrap_or(s.len());
    (&s[..i], &s[i..])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_table_jump_is_continuous_from_the_left_and_hold_from_writes_it() {
        let p = Profile::from_table(&[[0.0, 1293.0], [2.5, 1293.0], [2.5, 900.0], [4.0, 950.0]]).unwrap();
        assert_eq!(p.temperature(2.5), 1293.0);
        let after = p.temperature(2.5 + 1e-9);
        assert!(after > 900.0 && after < 900.001, "{after}");
        assert_eq!(p.temperature(3.25), 925.0);
        assert_eq!(p.split_points(0.0, 5.0, None), vec![2.5, 4.0]);
        // three rows at one time are not a jump
        let e = Profile::from_table(&[[0.0, 300.0], [1.0, 300.0], [1.0, 400.0], [1.0, 500.0]]).unwrap_err().to_string();
        assert!(e.contains("three may not"), "{e}");
        // a constant held at a new value from t = 2.5 is that table, bit for bit
        let c = Profile::constant(1293.0).unwrap().hold_from(2.5, 900.0).unwrap();
        assert_eq!(c.rows(), vec![[0.0, 1293.0], [2.5, 1293.0], [2.5, 900.0]]);
        assert_eq!(c, Profile::from_table(&c.rows()).unwrap());
        assert_eq!(c.temperature(2.5), 1293.0);
        assert_eq!(c.temperature(7.0), 900.0);
        assert!(Profile::constant(1293.0).unwrap().hold_from(1.0, -3.0).is_err());
    }

    #[test]
    fn schedule_gives_ramp_hold_cool() {
        let p = Profile::from_schedule("start 293 K, heat 20 K/min to 1203 K, hold 30 min, cool 20 K/min to 313 K").unwrap();
        let t_heat = (1203.0 - 293.0) / (20.0 / 60.0);
        assert_eq!(p.breakpoints().len(), 4);
        assert!((p.breakpoints()[1] - t_heat).abs() < 1e-9);
        assert!((p.temperature(t_heat / 2.0) - 748.0).abs() < 1e-9);
        assert_eq!(p.temperature(t_heat + 900.0), 1203.0);
        assert!((p.rate(1.0) - 1.0 / 3.0).abs() < 1e-15);
        let end = t_heat + 1800.0 + (1203.0 - 313.0) * 3.0;
        assert!((p.duration() - end).abs() < 1e-9);
        assert_eq!(p.temperature(end + 10.0), 313.0);
    }

    #[test]
    fn zero_hold_is_accepted_and_adds_no_breakpoint() {
        let a = Profile::from_schedule("start 793 K, heat 20 K/min to 1203 K, hold 0 min, cool 20 K/min to 313 K").unwrap();
        let b = Profile::from_schedule("start 793 K, heat 20 K/min to 1203 K, cool 20 K/min to 313 K").unwrap();
        assert_eq!(a, b);
        assert_eq!(a.breakpoints().len(), 3);
        assert!(Profile::from_schedule("start 793 K, hold -1 min").is_err());
    }

    #[test]
    fn celsius_and_hours() {
        let p = Profile::from_schedule("start 20 C, heat 100 K/h to 120 C").unwrap();
        assert!((p.temperature(0.0) - 293.15).abs() < 1e-12);
        assert!((p.duration() - 3600.0).abs() < 1e-9);
    }

    #[test]
    fn bad_schedules_are_rejected() {
        assert!(Profile::from_schedule("heat 20 K/min to 1203 K").is_err());
        assert!(Profile::from_schedule("start 293 K, cool 20 K/min to 1203 K").is_err());
        assert!(Profile::from_schedule("start 293 K, heat 20 furlongs to 1203 K").is_err());
        assert!(Profile::from_schedule("start -5 K").is_err());
        assert!(Profile::from_table(&[[0.0, 300.0], [0.0, 400.0]]).is_err());
    }

    #[test]
    fn split_points_find_kinks_and_crossings() {
        let p = Profile::from_table(&[[0.0, 1000.0], [100.0, 1200.0], [200.0, 1200.0]]).unwrap();
        let s = p.split_points(0.0, 150.0, Some(1156.0));
        assert_eq!(s.len(), 2);
        assert!((s[0] - 78.0).abs() < 1e-9);
        assert_eq!(s[1], 100.0);
    }
}
