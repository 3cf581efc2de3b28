//! The explicit sintering laws of `model = "…"`, chosen once when the case is parsed: [`LAWS`] is
//! the one list a new law is registered in; every per-law fact comes from its
//! [`SinterLaw`] impl, and the protocol runs generic over it behind one [`Law`] object.

use super::case::ExplicitSinterCase;
use super::machine::{Protocol, start_law};
use super::sample::Sample;
use crate::config::ranges::Range;
use crate::error::Error;
use crate::explicit::sinter::{FrenkelLaw, LawInputs, LudingLaw, SinterLaw, StateColumn};
use std::path::Path;

/// The laws by `model = "…"` (a new law: one line here).
pub static LAWS: &[Entry] = &[entry::<LudingLaw>(), entry::<FrenkelLaw>()];

/// One registered law: its name, its range table and its constructor from the case section.
pub struct Entry {
    pub name: &'static str,
    pub ranges: &'static [Range],
    pub build: fn(Option<toml::Value>, &LawInputs) -> Result<Box<dyn Law>, Error>,
}

const fn entry<M: SinterLaw>() -> Entry {
    Entry { name: M::NAME, ranges: M::RANGES, build: build::<M> }
}

fn build<M: SinterLaw>(section: Option<toml::Value>, case: &LawInputs) -> Result<Box<dyn Law>, Error> {
    Ok(Box::new(M::from_case(section, case)?))
}

/// The registered law named `name`.
pub fn find(name: &str) -> Option<&'static Entry> {
    LAWS.iter().find(|e| e.name == name)
}

/// The names of the laws for messages: `"luding" or "frenkel"`.
pub fn names() -> String {
    let quoted: Vec<String> = LAWS.iter().map(|e| format!("\"{}\"", e.name)).collect();
    match quoted.split_last() {
        Some((last, rest)) if !rest.is_empty() => format!("{} or {last}", rest.join(", ")),
        _ => quoted.join(""),
    }
}

/// A case's law, with the protocol instantiated for it (the one dispatch of the kind).
pub trait Law: Send + Sync + std::fmt::Debug {
    /// `model = "…"`.
    fn name(&self) -> &'static str;
    /// The history column of the law's state summary.
    fn state(&self) -> StateColumn;
    /// The explicit step of a sample of `case` at `pressure` [s] (`sinterdem check`).
    fn step(&self, case: &ExplicitSinterCase, pressure: f64) -> Result<f64, Error>;
    /// The protocol of `case` for this law, at its start or continued from `resume` (a
    /// checkpoint's text and path).
    fn protocol(&self, case: &ExplicitSinterCase, resume: Option<(&str, &Path)>, log: &mut dyn FnMut(&str)) -> Result<Box<dyn Protocol>, Error>;
    fn boxed(&self) -> Box<dyn Law>;
}

impl<M: SinterLaw> Law for M {
    fn name(&self) -> &'static str {
        M::NAME
    }
    fn state(&self) -> StateColumn {
        M::STATE
    }
    fn step(&self, case: &ExplicitSinterCase, pressure: f64) -> Result<f64, Error> {
        Ok(Sample::new(case, self.clone(), pressure)?.driver.settings.dt)
    }
    fn protocol(&self, case: &ExplicitSinterCase, resume: Option<(&str, &Path)>, log: &mut dyn FnMut(&str)) -> Result<Box<dyn Protocol>, Error> {
        start_law(case, self.clone(), resume, log)
    }
    fn boxed(&self) -> Box<dyn Law> {
        Box::new(self.clone())
    }
}

impl Clone for Box<dyn Law> {
    fn clone(&self) -> Self {
        self.boxed()
    }
}
