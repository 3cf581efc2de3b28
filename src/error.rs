//! Error types: one top-level [`Error`] wrapping the four families of the
//! docs/design.md (`ConfigError`, `ModelError`, `SolveError`, `IoError`).
//! Library code never panics on user input; it returns one of these.

use thiserror::Error;

/// A number as a user reads it: plain between 1e-4 and 1e7, scientific notation otherwise
/// (a tiny value such as 5e-324 prints as `5e-324`, not as a 300-digit decimal).
pub fn fmt_value(x: f64) -> String {
    if x == 0.0 || !x.is_finite() || (1e-4..1e7).contains(&x.abs()) { format!("{x}") } else { format!("{x:e}") }
}

/// A case file or command-line value that is malformed or non-physical.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum ConfigError {
    /// A numeric key outside its allowed interval.
    #[error("{key} = {} is out of range: allowed {range} ({unit})", fmt_value(*value))]
    OutOfRange { key: String, value: f64, range: String, unit: String },
    /// A key the schema does not know, or a value of the wrong type or form.
    #[error("{0}")]
    Invalid(String),
    /// A combination of keys that cannot hold together.
    #[error("{key}: {message}")]
    Inconsistent { key: String, message: String },
}

impl ConfigError {
    /// The case key the error names (out of range, inconsistent), if any.
    pub fn key(&self) -> Option<&str> {
        match self {
            ConfigError::OutOfRange { key, .. } | ConfigError::Inconsistent { key, .. } => Some(key),
            ConfigError::Invalid(_) => None,
        }
    }
    pub fn invalid(msg: impl Into<String>) -> Self {
        ConfigError::Invalid(msg.into())
    }
    pub fn inconsistent(key: impl Into<String>, message: impl Into<String>) -> Self {
        ConfigError::Inconsistent { key: key.into(), message: message.into() }
    }
}

/// A physical model left its domain of validity (e.g. a neck larger than the smaller particle).
#[derive(Debug, Error, Clone, PartialEq)]
#[error("model error{}: {message}", context.as_ref().map(|c| format!(" ({c})")).unwrap_or_default())]
pub struct ModelError {
    pub message: String,
    /// Where it happened: contact id, time, state.
    pub context: Option<String>,
}

impl ModelError {
    pub fn new(message: impl Into<String>) -> Self {
        ModelError { message: message.into(), context: None }
    }
    pub fn with_context(mut self, context: impl Into<String>) -> Self {
        let c = context.into();
        self.context = Some(match self.context.take() {
            Some(old) => format!("{c}; {old}"),
            None => c,
        });
        self
    }
}

/// A linear or nonlinear solve that failed (not SPD, no convergence, non-finite result).
#[derive(Debug, Error, Clone, PartialEq)]
#[error("solver error in {stage}: {message}{}", if residuals.is_empty() { String::new() } else { format!(" (residual history: {})", residuals.iter().map(|r| format!("{r:.3e}")).collect::<Vec<_>>().join(", ")) })]
pub struct SolveError {
    pub stage: String,
    pub message: String,
    /// Residual history, newest last.
    pub residuals: Vec<f64>,
}

impl SolveError {
    pub fn new(stage: impl Into<String>, message: impl Into<String>) -> Self {
        SolveError { stage: stage.into(), message: message.into(), residuals: Vec::new() }
    }
}

/// Reading or writing a file failed.
#[derive(Debug, Error)]
#[error("{path}: {message}")]
pub struct IoError {
    pub path: String,
    pub message: String,
}

impl IoError {
    pub fn new(path: impl AsRef<std::path::Path>, message: impl std::fmt::Display) -> Self {
        IoError { path: path.as_ref().display().to_string(), message: message.to_string() }
    }
}

/// Any sinterdem error.
#[derive(Debug, Error)]
pub enum Error {
    #[error("configuration error: {0}")]
    Config(#[from] ConfigError),
    #[error("{0}")]
    Model(#[from] ModelError),
    #[error("{0}")]
    Solve(#[from] SolveError),
    #[error("i/o error: {0}")]
    Io(#[from] IoError),
}

impl Error {
    /// The class of the error as the Python package names it: `ConfigError`, `ModelError`,
    /// `SolveError` or `IoError`.
    pub fn class_name(&self) -> &'static str {
        match self {
            Error::Config(_) => "ConfigError",
            Error::Model(_) => "ModelError",
            Error::Solve(_) => "SolveError",
            Error::Io(_) => "IoError",
        }
    }

    /// The exit code of the command line for this error class (docs/outputs.md, "Exit codes"):
    /// 1 configuration, 3 model, 4 solver, 5 input/output (2 is a command-line usage error).
    pub fn exit_code(&self) -> i32 {
        match self {
            Error::Config(_) => 1,
            Error::Model(_) => 3,
            Error::Solve(_) => 4,
            Error::Io(_) => 5,
        }
    }
}

pub type Result<T, E = Error> = std::result::Result<T, E>;
