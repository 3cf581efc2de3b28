//! Plausibility of derived quantities (`sinterdem check`, docs/case-file.md "Plausibility"):
//! a case whose every key is in range can still ask for a run that cannot finish — more steps
//! than any machine will take, a step so small that `t + dt == t`, or more particles than the
//! memory holds. These checks refuse such cases before anything is built, with an estimate.

use crate::error::{ConfigError, fmt_value};

/// Most steps a run may imply (`end/dt`, `end/dt_max`).
pub const MAX_STEPS: f64 = 1e9;

/// Estimated memory per particle of a run [bytes] (particles, contacts ≈ 6 per particle, sparse
/// matrices and their factors; measured on the bundled cases with a margin).
pub const BYTES_PER_PARTICLE_HEAT: f64 = 4096.0;
/// Compact runs add the 7-DOF contact states and the 6-DOF mechanics system: peak resident
/// memory measured 7.9–8.2 kB per particle on random packings (2.6 contacts per particle, 10⁴–10⁶
/// particles) and 11.2 kB on the touching FCC lattice (5.8 contacts per particle, AMG-PCG),
/// `sinterdem bench coupled` (docs/coupled.md "Scaling"); 16 kB leaves a margin of 1.4 over
/// the densest.
pub const BYTES_PER_PARTICLE_COMPACT: f64 = 16384.0;
/// Packing generation (explicit DEM: particles, cell list, contacts).
pub const BYTES_PER_PARTICLE_GENERATE: f64 = 2048.0;

/// `MemAvailable` of /proc/meminfo [bytes]; `SINTERDEM_MEMORY_AVAILABLE` (bytes) overrides it;
/// None where neither is known (the memory check is then skipped).
pub fn available_memory() -> Option<f64> {
    if let Some(v) = std::env::var("SINTERDEM_MEMORY_AVAILABLE").ok().and_then(|s| s.trim().parse::<f64>().ok()) {
        return Some(v);
    }
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024.0)
}

/// Refuses `particles` particles at `bytes_per_particle` when the estimate exceeds the available
/// memory; `key` names what sets the count.
pub fn check_memory(key: &str, particles: f64, bytes_per_particle: f64) -> Result<(), ConfigError> {
    let need = particles * bytes_per_particle;
    match available_memory() {
        Some(avail) if need > avail => Err(ConfigError::inconsistent(
            key,
            format!(
                "{} particles need about {:.1} GB ({} bytes per particle), but only {:.1} GB of memory are available",
                fmt_value(particles),
                need / 1e9,
                bytes_per_particle,
                avail / 1e9
            ),
        )),
        _ => Ok(()),
    }
}

/// Refuses a run that implies more than [`MAX_STEPS`] steps, or whose step vanishes against the
/// end time (`end + dt == end`: time could not advance).
pub fn check_steps(key: &str, end: f64, dt: f64) -> Result<(), ConfigError> {
    let steps = end / dt;
    if !(steps <= MAX_STEPS) {
        return Err(ConfigError::inconsistent(
            key,
            format!("time.end / {key} = {} / {} implies about {:.0e} steps (at most {} allowed)", fmt_value(end), fmt_value(dt), steps, fmt_value(MAX_STEPS)),
        ));
    }
    Ok(())
}

/// What a value typical of a wrong unit leads to: refused, or (where legitimate values exist) a
/// warning.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SlipAction {
    Refuse,
    Warn,
}

/// A unit slip (docs/case-file.md "Unit slips"): a value of `key` that lies inside the key's range
/// but is typical of the wrong unit — below `below` or above `above` (SI unit `unit`).
#[derive(Debug, Clone, Copy)]
pub struct Slip {
    /// Key pattern as in the range tables (`*`: any one segment).
    pub key: &'static str,
    pub below: f64,
    pub above: f64,
    pub unit: &'static str,
    /// The plausible values, in words with their unit.
    pub plausible: &'static str,
    /// The likely slip, as a question with the conversion.
    pub hint: &'static str,
    pub action: SlipAction,
    /// Zero is a legitimate value (a switch), not a slip.
    pub zero_ok: bool,
}

const fn slip(
    key: &'static str,
    below: f64,
    above: f64,
    unit: &'static str,
    plausible: &'static str,
    hint: &'static str,
    action: SlipAction,
    zero_ok: bool,
) -> Slip {
    Slip { key, below, above, unit, plausible, hint, action, zero_ok }
}

const Q_PLAUSIBLE: &str = "activation energies of diffusion and viscous flow lie between 10 kJ/mol and 1000 kJ/mol, i.e. [1e4, 1e6] J/mol";
const Q_HINT: &str = "did you write kJ/mol? Q is in J/mol (220 kJ/mol is 220e3)";
const E_PLAUSIBLE: &str = "powders that sinter have Young's moduli between 1 GPa (polymers) and 1000 GPa (tungsten carbide), i.e. [1e9, 1e12] Pa";
const E_HINT: &str = "did you write GPa or MPa? E is in Pa (193 GPa is 193e9)";
const RHO_PLAUSIBLE: &str = "solid densities lie between 500 kg/m^3 (polymers) and 23000 kg/m^3 (osmium)";
const RHO_HINT: &str = "did you write g/cm^3? rho is in kg/m^3 (7.99 g/cm^3 is 7990)";
const C_PLAUSIBLE: &str = "specific heat capacities of solids above 100 K lie between 100 and 3000 J/(kg K)";
const C_HINT: &str = "did you write kJ/(kg K)? c is in J/(kg K) (0.5 kJ/(kg K) is 500)";
const R_PLAUSIBLE: &str = "powder particles have radii between 10 nm and 1 cm, i.e. [1e-8, 1e-2] m";
const R_HINT: &str = "did you write mm? radii are in m (20 µm is 20e-6)";
const T_PLAUSIBLE: &str = "sintering and heating temperatures lie above 100 K";
const T_HINT: &str = "did you write °C? temperatures are in K (20 °C is 293.15 K; a schedule may write `C`)";

/// The unit slips `check` and `run` catch (docs/case-file.md "Unit slips"). Refused where no
/// legitimate value of a sintering case lies there; warned where one does (soft polymers, large
/// spheres, a cryogenic heat case).
pub static SLIPS: &[Slip] = &[
    slip("materials.*.phases.*.q_surface", 1e4, f64::INFINITY, "J/mol", Q_PLAUSIBLE, Q_HINT, SlipAction::Refuse, true),
    slip("materials.*.phases.*.q_gb", 1e4, f64::INFINITY, "J/mol", Q_PLAUSIBLE, Q_HINT, SlipAction::Refuse, true),
    slip("materials.*.phases.*.q_lattice", 1e4, f64::INFINITY, "J/mol", Q_PLAUSIBLE, Q_HINT, SlipAction::Refuse, true),
    slip("frenkel.activation_energy", 1e4, f64::INFINITY, "J/mol", Q_PLAUSIBLE, Q_HINT, SlipAction::Refuse, true),
    slip("frenkel.gb_activation_energy", 1e4, f64::INFINITY, "J/mol", Q_PLAUSIBLE, Q_HINT, SlipAction::Refuse, true),
    slip("materials.*.young_modulus", 1e6, f64::INFINITY, "Pa", E_PLAUSIBLE, E_HINT, SlipAction::Refuse, false),
    slip(
        "materials.*.young_modulus",
        1e9,
        f64::INFINITY,
        "Pa",
        E_PLAUSIBLE,
        "softer than any metal or ceramic; right only for a polymer powder",
        SlipAction::Warn,
        false,
    ),
    slip("materials.*.density", 100.0, f64::INFINITY, "kg/m^3", RHO_PLAUSIBLE, RHO_HINT, SlipAction::Refuse, false),
    slip("sample.density", 100.0, f64::INFINITY, "kg/m^3", RHO_PLAUSIBLE, RHO_HINT, SlipAction::Refuse, false),
    slip("materials.*.heat_capacity", 20.0, f64::INFINITY, "J/(kg K)", C_PLAUSIBLE, C_HINT, SlipAction::Refuse, false),
    slip("particles.radius", 0.0, 1e-2, "m", R_PLAUSIBLE, R_HINT, SlipAction::Warn, false),
    slip("particles.radius_2", 0.0, 1e-2, "m", R_PLAUSIBLE, R_HINT, SlipAction::Warn, false),
    slip("sample.mean_radius", 0.0, 1e-2, "m", R_PLAUSIBLE, R_HINT, SlipAction::Warn, false),
];

/// Temperature keys of heating (a profile's temperatures are found by [`unit_slips`] itself).
pub const TEMPERATURE_KEYS: &[&str] = &[
    "particles.initial_temperature",
    "temperature.constant",
    "temperature.start_temperature",
    "temperature.peak_temperature",
    "temperature.end_temperature",
    "protocol.temperature_cold",
    "protocol.temperature_hot",
];

/// Below this temperature [K] a heating temperature is taken for a °C value (refused in the
/// sintering kinds, warned in heat cases, where a cryogenic bath is legitimate).
pub const T_SLIP: f64 = 100.0;

fn slip_key_matches(pattern: &str, key: &str) -> bool {
    let (p, k): (Vec<&str>, Vec<&str>) = (pattern.split('.').collect(), key.split('.').collect());
    p.len() == k.len() && p.iter().zip(&k).all(|(a, b)| *a == "*" || a == b)
}

/// Every number of `v` with its dotted key (array elements by index).
fn numbers(prefix: &str, v: &toml::Value, out: &mut Vec<(String, f64)>) {
    let join = |k: &str| if prefix.is_empty() { k.to_string() } else { format!("{prefix}.{k}") };
    match v {
        toml::Value::Table(t) => t.iter().for_each(|(k, x)| numbers(&join(k), x, out)),
        toml::Value::Array(a) => a.iter().enumerate().for_each(|(i, x)| numbers(&join(&i.to_string()), x, out)),
        toml::Value::Float(x) => out.push((prefix.to_string(), *x)),
        toml::Value::Integer(i) => out.push((prefix.to_string(), *i as f64)),
        _ => {}
    }
}

/// The heating profiles of `v` (every `profile` table, and the `[temperature]` of a pair case):
/// (key, lowest temperature [K]). Profiles that do not parse are left to the kind's own check.
fn profile_minima(prefix: &str, v: &toml::Value, out: &mut Vec<(String, f64)>) {
    let toml::Value::Table(t) = v else {
        if let toml::Value::Array(a) = v {
            a.iter().enumerate().for_each(|(i, x)| profile_minima(&format!("{prefix}.{i}"), x, out));
        }
        return;
    };
    let name = prefix.rsplit('.').next().unwrap_or_default();
    if name == "profile" || prefix == "temperature" {
        if let Some(s) = t.get("schedule").and_then(|s| s.as_str())
            && let Ok(p) = crate::profile::Profile::from_schedule(s)
        {
            out.push((format!("{prefix}.schedule"), p.range().0));
        }
        if let Some(rows) = t.get("table").and_then(|r| r.as_array()) {
            let low = rows.iter().filter_map(|r| r.as_array()?.get(1)?.as_float()).fold(f64::INFINITY, f64::min);
            if low.is_finite() {
                out.push((format!("{prefix}.table"), low));
            }
        }
        if name == "profile"
            && let Some(c) = t.get("constant").and_then(|c| c.as_float().or_else(|| c.as_integer().map(|i| i as f64)))
        {
            out.push((format!("{prefix}.constant"), c));
        }
    }
    for (k, x) in t {
        let key = if prefix.is_empty() { k.clone() } else { format!("{prefix}.{k}") };
        profile_minima(&key, x, out);
    }
}

/// The name of the material (and phase) a `materials.I[.phases.J].…` key belongs to, for messages.
fn owner(case: &toml::Value, key: &str) -> String {
    let seg: Vec<&str> = key.split('.').collect();
    if seg.first() != Some(&"materials") {
        return String::new();
    }
    let name = |v: Option<&toml::Value>| v.and_then(|m| m.get("name")).and_then(|n| n.as_str()).map(String::from);
    let mat = seg.get(1).and_then(|i| i.parse::<usize>().ok()).and_then(|i| case.get("materials")?.as_array()?.get(i));
    let mut s = match name(mat) {
        Some(n) => format!(" (material \"{n}\""),
        None => return String::new(),
    };
    if seg.get(2) == Some(&"phases")
        && let Some(p) = name(seg.get(3).and_then(|j| j.parse::<usize>().ok()).and_then(|j| mat?.get("phases")?.as_array()?.get(j)))
    {
        s.push_str(&format!(", phase \"{p}\""));
    }
    s.push(')');
    s
}

/// Values of `case` typical of the wrong unit (docs/case-file.md "Unit slips"): the first one
/// that is refused is the error (key, value, the likely slip, the plausible range with its
/// unit); the others are returned as warnings. Checked by `check` and at the start of `run`, after
/// includes and `--set` are applied.
pub fn unit_slips(case: &toml::Value) -> Result<Vec<String>, ConfigError> {
    let mut warnings = Vec::new();
    let mut all = Vec::new();
    numbers("", case, &mut all);
    for (key, v) in &all {
        for s in SLIPS.iter().filter(|s| slip_key_matches(s.key, key)) {
            if !(v.is_finite() && (*v < s.below || *v > s.above)) || (s.zero_ok && *v == 0.0) {
                continue;
            }
            let side = if *v < s.below { "small" } else { "large" };
            let msg = format!("{} {}{} is implausibly {side}: {}; {}", fmt_value(*v), s.unit, owner(case, key), s.hint, s.plausible);
            match s.action {
                SlipAction::Refuse => return Err(ConfigError::inconsistent(key.clone(), msg)),
                SlipAction::Warn => {
                    warnings.push(format!("{key} = {msg}"));
                    break;
                }
            }
        }
    }
    // temperatures of heating: °C written for K
    let kind = case.get("kind").and_then(|k| k.as_str()).unwrap_or("heat");
    let refuse = matches!(kind, "compact" | "pair" | "explicit_sinter");
    let mut temps: Vec<(String, f64)> = all.iter().filter(|(k, _)| TEMPERATURE_KEYS.contains(&k.as_str())).cloned().collect();
    profile_minima("", case, &mut temps);
    for (key, t) in temps {
        if !(t.is_finite() && t < T_SLIP) {
            continue;
        }
        let what = if key.ends_with(".schedule") || key.ends_with(".table") { "the profile reaches " } else { "" };
        let msg = format!("{what}{} K is implausibly low: {T_HINT}; {T_PLAUSIBLE} (a {kind} case)", fmt_value(t));
        if refuse {
            return Err(ConfigError::inconsistent(key, msg));
        }
        warnings.push(format!("{key}: {msg}"));
    }
    Ok(warnings)
}

/// The heating profiles of `v` that `spec` parses (every `profile` table, and the `[temperature]`
/// of a pair case written as a schedule or a table): (key, profile).
fn profiles(prefix: &str, v: &toml::Value, out: &mut Vec<(String, crate::profile::Profile)>) {
    match v {
        toml::Value::Array(a) => a.iter().enumerate().for_each(|(i, x)| profiles(&format!("{prefix}.{i}"), x, out)),
        toml::Value::Table(t) => {
            let name = prefix.rsplit('.').next().unwrap_or_default();
            if (name == "profile" || prefix == "temperature")
                && (t.contains_key("schedule") || t.contains_key("table"))
                && let Ok(spec) = v.clone().try_into::<crate::profile::ProfileSpec>()
                && let Ok(p) = crate::profile::Profile::from_spec(&spec, prefix)
            {
                out.push((prefix.to_string(), p));
            }
            for (k, x) in t {
                profiles(&if prefix.is_empty() { k.clone() } else { format!("{prefix}.{k}") }, x, out);
            }
        }
        _ => {}
    }
}

/// The end-time key of a case's kind: `time.end`, or `pair.end_time` for a pair case (None for the
/// kinds without one: generate, explicit_sinter, whose protocol sets its own times).
fn end_key(case: &toml::Value) -> Option<(&'static str, &'static str)> {
    match case.get("kind").and_then(|k| k.as_str()).unwrap_or("heat") {
        "heat" | "compact" => Some(("time", "end")),
        "pair" => Some(("pair", "end_time")),
        _ => None,
    }
}

/// The heating profiles of a case that end (a `schedule` or `table`; constant profiles have no
/// end), with their keys.
fn finite_profiles(case: &toml::Value) -> Vec<(String, crate::profile::Profile)> {
    let mut list = Vec::new();
    profiles("", case, &mut list);
    list.retain(|(_, p)| !p.is_constant() && p.duration().is_finite() && p.duration() > 0.0);
    list
}

/// `time.end` (a pair's `pair.end_time`) defaults to the end of the case's heating profile(s),
/// the latest one when there are several (issue 25 item 3, docs/case-file.md "End time and
/// schedule"): inserted into the resolved case when the key is absent and a profile ends. Returns
/// the log line saying so (None: an end was given, or no profile ends and the kind's own
/// "missing end" error stands).
pub fn default_end(case: &mut toml::Value) -> Result<Option<String>, ConfigError> {
    let Some((sec, key)) = end_key(case) else { return Ok(None) };
    if case.get(sec).and_then(|t| t.get(key)).is_some() {
        return Ok(None);
    }
    let list = finite_profiles(case);
    let Some((pkey, stop)) = list.iter().map(|(k, p)| (k.clone(), p.duration())).max_by(|a, b| a.1.total_cmp(&b.1)) else {
        // a pair case says so itself ("required when the temperature history has no end")
        if sec == "time" {
            return Err(ConfigError::inconsistent(
                format!("{sec}.{key}"),
                format!("missing, and no heating profile of the case ends (all constant) to take the end time from: give {sec}.{key} [s]"),
            ));
        }
        return Ok(None);
    };
    let Some(table) = case.as_table_mut().and_then(|t| t.entry(sec).or_insert_with(|| toml::Value::Table(toml::Table::new())).as_table_mut()) else {
        return Ok(None);
    };
    table.insert(key.to_string(), toml::Value::Float(stop));
    Ok(Some(format!("{sec}.{key} not given: the end of the heating profile {pkey}, {} s", tidy(stop))))
}

/// `x` to 10 significant digits, for messages: a schedule's end summed from its segments
/// (3899.8199999999997 s) reads as written (3899.82 s).
fn tidy(x: f64) -> String {
    fmt_value(format!("{x:.9e}").parse::<f64>().unwrap_or(x))
}

/// What a case's end time cuts from its heating profiles (docs/case-file.md "End time and
/// schedule"), as (warnings, notes): a warning per profile that ends after the run's end
/// (`time.end`, a pair's `pair.end_time`), naming the temperature the run stops at, and whether
/// the profile's peak is reached. (Notes: none today; kept for the callers' log lines.)
pub fn schedule_end_warnings(case: &toml::Value) -> (Vec<String>, Vec<String>) {
    let num = |v: Option<&toml::Value>| v.and_then(|x| x.as_float().or_else(|| x.as_integer().map(|i| i as f64)));
    let (key, end) = match (num(case.get("time").and_then(|t| t.get("end"))), num(case.get("pair").and_then(|t| t.get("end_time")))) {
        (Some(e), _) => ("time.end", e),
        (None, Some(e)) => ("pair.end_time", e),
        _ => return (Vec::new(), Vec::new()),
    };
    let mut warnings = Vec::new();
    for (pkey, p) in finite_profiles(case) {
        let stop = p.duration();
        // a relative tolerance: an end written with fewer digits than the schedule's sum
        if !(end < stop * (1.0 - 1e-9)) {
            continue;
        }
        let (_, peak) = p.range();
        let t_end = p.temperature(end);
        let head = format!("{key} = {} s ends before the heating profile {pkey} (which ends at {} s)", tidy(end), tidy(stop));
        let tail = format!("set {key} = {} or leave it out to run the whole schedule", tidy(stop));
        warnings.push(match p.first_reaching(peak, stop) {
            Some(t_peak) if t_peak > end => {
                format!("{head}: the run stops at {t_end:.1} K, below the profile's peak {peak:.1} K (reached at {} s); {tail}", tidy(t_peak))
            }
            _ => format!("{head}: the run stops at {t_end:.1} K, after the profile's peak {peak:.1} K, without the rest of its hold or cooling; {tail}"),
        });
    }
    // output times after the end are never reached: said by `check` and by the run alike (a note:
    // shortening time.end of a bundled case for a quick look is common; issue 38)
    let mut notes = Vec::new();
    if key == "time.end" {
        for list in ["conductivity_at", "correction_histogram_at"] {
            let after: Vec<String> = case
                .get("output")
                .and_then(|o| o.get(list))
                .and_then(|a| a.as_array())
                .into_iter()
                .flatten()
                .filter_map(|v| num(Some(v)))
                .filter(|&t| t > end * (1.0 + 1e-12))
                .map(tidy)
                .collect();
            if !after.is_empty() {
                notes.push(format!("output.{list}: {} s after time.end = {} s: not written (the run ends before)", after.join(", "), tidy(end)));
            }
        }
    }
    (warnings, notes)
}

#[cfg(test)]
mod tests {
    use super::*;
    #[test]
    fn steps_and_memory() {
        let e = check_steps("time.dt", 1.0, 1e-300).unwrap_err().to_string();
        assert!(e.contains("about 1e300 steps"), "{e}");
        assert!(check_steps("time.dt", 1.0, 1e-3).is_ok());
        let e = check_memory("particles.cells", 1e12, 1e3).unwrap_err().to_string();
        assert!(e.contains("GB"), "{e}");
    }
}
