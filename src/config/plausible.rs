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
/// Compact runs add the 7-DOF contact states and the 6-DOF mechanics system.
pub const BYTES_PER_PARTICLE_COMPACT: f64 = 32768.0;
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
