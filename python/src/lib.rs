//! `sinterdem._native`: the Rust half of the Python package. Everything here is a thin call into
//! the sinterdem library (the one run API `sinterdem::kinds::run`, `calibrate::check_file`,
//! `study::run_study`, `calibrate::run_file`, `cli::main`); the Python layer (`sinterdem/*.py`)
//! adds the objects users hold (Case, RunResult, …). Nothing of the simulator is written twice.

use numpy::{PyArray1, PyArrayMethods};
use pyo3::exceptions::{PyKeyError, PyTypeError};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyList, PyString, PyTuple};
use sinterdem::config;
use sinterdem::error::{ConfigError, Error};
use std::path::{Path, PathBuf};

/// A sinterdem error as the Python exception of its class (`sinterdem.ConfigError`, …), with
/// the text the command line prints after `error: ` and the structured fields of a
/// configuration error. `file` is the case file the error is located in, `sets` the overrides
/// given so far (an error in a key they set says so, as `--set` does).
fn to_py_err(py: Python<'_>, e: Error, file: Option<&Path>, sets: &[String]) -> PyErr {
    if let Some(m) = internal_message(&e) {
        let message = format!("internal error in sinterdem ({m}); this is a bug: please report it with the case that caused it");
        return py_error(py, "Error", message, ErrFields::default());
    }
    let (mut key, mut value, mut allowed, mut unit, mut line, mut located_file) = (None, None, None, None, None, None);
    if let Error::Config(ce) = &e {
        key = ce.key().map(str::to_string);
        if let ConfigError::OutOfRange { value: v, range, unit: u, .. } = ce {
            value = Some(*v);
            allowed = Some(range.clone());
            unit = Some(u.clone());
        }
        if let (Some(k), Some(f)) = (key.as_deref(), file) {
            let k = config::messages::normalise_key(k);
            let k = k.split(' ').next().unwrap_or_default();
            let set_here = sets.iter().any(|o| o.split_once('=').is_some_and(|(a, _)| config::messages::normalise_key(a.trim()) == k));
            if !set_here && let Ok(text) = std::fs::read_to_string(f) {
                line = config::messages::key_position(&text, k).map(|(l, _)| l);
                located_file = line.map(|_| f.display().to_string());
            }
        }
    }
    let class = e.class_name();
    let e = match file {
        Some(f) => config::messages::locate(e, f, sets),
        None => config::messages::locate(e, Path::new(""), sets),
    };
    let message = e.to_string();
    py_error(py, class, message, ErrFields { key, value, allowed, unit, file: located_file, line })
}

/// Marks an [`Error`] that stands for a panic of the library ([`shielded`]): raised as
/// `sinterdem.Error` with a one-line message, never as pyo3's `PanicException` (a
/// `BaseException` with a Rust backtrace, issue 38 item 4).
const INTERNAL: &str = "\u{1}internal: ";

/// The error of a panic (or a lost thread) with `message`.
fn internal_error(message: &str) -> Error {
    ConfigError::invalid(format!("{INTERNAL}{message}")).into()
}

fn internal_message(e: &Error) -> Option<&str> {
    match e {
        Error::Config(ConfigError::Invalid(m)) => m.strip_prefix(INTERNAL),
        _ => None,
    }
}

fn is_internal(e: &Error) -> bool {
    internal_message(e).is_some()
}

/// The message of the latest panic, as the hook of [`quiet_panics`] kept it.
static LAST_PANIC: std::sync::Mutex<Option<String>> = std::sync::Mutex::new(None);

/// Replaces Rust's panic printout (thread name, file, line, backtrace hint on stderr) by a note
/// kept for [`shielded`]: a panic reaches Python users as one `sinterdem.Error`.
fn quiet_panics() {
    std::panic::set_hook(Box::new(|info| {
        let payload = info.payload();
        let msg = payload.downcast_ref::<&str>().map(|s| s.to_string()).or_else(|| payload.downcast_ref::<String>().cloned()).unwrap_or_else(|| "panic".into());
        let at = info.location().map(|l| format!(" at {}:{}", l.file(), l.line())).unwrap_or_default();
        *LAST_PANIC.lock().unwrap_or_else(|e| e.into_inner()) = Some(format!("{msg}{at}"));
    }));
}

/// Runs `f`, turning a panic into [`internal_error`].
fn shielded<T>(f: impl FnOnce() -> Result<T, Error>) -> Result<T, Error> {
    match std::panic::catch_unwind(std::panic::AssertUnwindSafe(f)) {
        Ok(r) => r,
        Err(_) => {
            let m = LAST_PANIC.lock().unwrap_or_else(|e| e.into_inner()).take().unwrap_or_else(|| "panic".into());
            Err(internal_error(&m))
        }
    }
}

/// The structured fields of a sinterdem exception (`sinterdem.ConfigError.key`, …).
#[derive(Default)]
struct ErrFields {
    key: Option<String>,
    value: Option<f64>,
    allowed: Option<String>,
    unit: Option<String>,
    file: Option<String>,
    line: Option<usize>,
}

/// The Python exception `sinterdem.<class>(message, **fields)`.
fn py_error(py: Python<'_>, class: &str, message: String, f: ErrFields) -> PyErr {
    let build = || -> PyResult<PyErr> {
        let cls = py.import("sinterdem._errors")?.getattr(class)?;
        let kw = PyDict::new(py);
        kw.set_item("key", f.key)?;
        kw.set_item("value", f.value)?;
        kw.set_item("allowed", f.allowed)?;
        kw.set_item("unit", f.unit)?;
        kw.set_item("file", f.file)?;
        kw.set_item("line", f.line)?;
        Ok(PyErr::from_value(cls.call((message,), Some(&kw))?))
    };
    build().unwrap_or_else(|err| err)
}

/// Deepest nesting of tables and arrays a case value may have: a case file nests a few levels
/// (`thermal.furnace.profile.table`); a self-referential dict or list would recurse until the
/// stack overflows (issue 38 item 4).
const MAX_DEPTH: usize = 64;

/// A Python value (bool, int, float, str, dict, list, tuple, numpy scalar) as TOML; nesting
/// deeper than [`MAX_DEPTH`] (or a dict or list that contains itself) is a ConfigError naming
/// the key path where it happened.
fn py_to_toml(v: &Bound<'_, PyAny>) -> PyResult<toml::Value> {
    py_to_toml_at(v, "", 0)
}

fn py_to_toml_at(v: &Bound<'_, PyAny>, at: &str, depth: usize) -> PyResult<toml::Value> {
    if depth > MAX_DEPTH && (v.is_instance_of::<PyDict>() || v.is_instance_of::<PyList>() || v.is_instance_of::<PyTuple>()) {
        let key = if at.is_empty() { "<case>".to_string() } else { at.to_string() };
        let message =
            format!("{key}: tables and lists nested deeper than {MAX_DEPTH} levels (a dict or list that contains itself?); a case file nests a few levels");
        let fields = ErrFields {
            key: Some(key),
            value: Some((depth + 1) as f64),
            allowed: Some(format!("[0, {MAX_DEPTH}]")),
            unit: Some("nesting levels".into()),
            ..Default::default()
        };
        return Err(py_error(v.py(), "ConfigError", message, fields));
    }
    let child = |k: &str| if at.is_empty() { k.to_string() } else { format!("{at}.{k}") };
    if v.is_instance_of::<PyBool>() {
        return Ok(toml::Value::Boolean(v.extract()?));
    }
    if v.is_instance_of::<PyInt>() {
        // a TOML integer is 64-bit: a larger one is the key's error, not pyo3's bare
        // "Python int too large to convert to C long" (found by python/tests/test_fuzz.py)
        return match v.extract::<i64>() {
            Ok(i) => Ok(toml::Value::Integer(i)),
            Err(_) => {
                let shown = v.str().map(|s| s.to_string()).unwrap_or_default();
                let message = format!(
                    "{at} = {shown}: a whole number in a case file is 64-bit, in [-2^63, 2^63 - 1] (write it as a float, e.g. {shown}.0, if it is a quantity)"
                );
                let fields = ErrFields {
                    key: Some(at.to_string()),
                    value: v.extract::<f64>().ok(),
                    allowed: Some("[-9223372036854775808, 9223372036854775807]".into()),
                    unit: Some("1".into()),
                    ..Default::default()
                };
                Err(py_error(v.py(), "ConfigError", message, fields))
            }
        };
    }
    if v.is_instance_of::<PyFloat>() {
        return Ok(toml::Value::Float(v.extract()?));
    }
    if let Ok(s) = v.cast::<PyString>() {
        return Ok(toml::Value::String(s.extract::<String>()?));
    }
    if let Ok(d) = v.cast::<PyDict>() {
        let mut t = toml::Table::new();
        for (k, x) in d.iter() {
            let k: String = k.extract().map_err(|_| PyTypeError::new_err(format!("case keys must be strings, not {k:?}")))?;
            let sub = py_to_toml_at(&x, &child(&k), depth + 1)?;
            t.insert(k, sub);
        }
        return Ok(toml::Value::Table(t));
    }
    if v.is_instance_of::<PyList>() || v.is_instance_of::<PyTuple>() {
        return Ok(toml::Value::Array(v.try_iter()?.enumerate().map(|(i, x)| py_to_toml_at(&x?, &child(&i.to_string()), depth + 1)).collect::<PyResult<_>>()?));
    }
    // numpy scalars and anything else with __index__ / __float__
    if let Ok(i) = v.call_method0("__index__").and_then(|i| i.extract::<i64>()) {
        return Ok(toml::Value::Integer(i));
    }
    if let Ok(x) = v.call_method0("__float__").and_then(|x| x.extract::<f64>()) {
        return Ok(toml::Value::Float(x));
    }
    if v.hasattr("tolist")? {
        return py_to_toml_at(&v.call_method0("tolist")?, at, depth + 1);
    }
    Err(PyTypeError::new_err(format!("{} cannot be written in a case file (use bool, int, float, str, dict or list)", v.get_type().name()?)))
}

/// A TOML value as Python (dates as strings).
fn toml_to_py<'py>(py: Python<'py>, v: &toml::Value) -> PyResult<Bound<'py, PyAny>> {
    Ok(match v {
        toml::Value::String(s) => s.into_pyobject(py)?.into_any(),
        toml::Value::Integer(i) => i.into_pyobject(py)?.into_any(),
        toml::Value::Float(x) => x.into_pyobject(py)?.into_any(),
        toml::Value::Boolean(b) => PyBool::new(py, *b).to_owned().into_any(),
        toml::Value::Datetime(d) => d.to_string().into_pyobject(py)?.into_any(),
        toml::Value::Array(a) => PyList::new(py, a.iter().map(|x| toml_to_py(py, x)).collect::<PyResult<Vec<_>>>()?)?.into_any(),
        toml::Value::Table(t) => {
            let d = PyDict::new(py);
            for (k, x) in t {
                d.set_item(k, toml_to_py(py, x)?)?;
            }
            d.into_any()
        }
    })
}

/// A case as the command line holds it: the parsed file (includes expanded) plus the `--set`
/// overrides in order. Runs and checks pass both to the library exactly as `sinterdem run FILE
/// --set …` does.
#[pyclass(module = "sinterdem._native")]
#[derive(Clone)]
struct CaseCore {
    value: toml::Value,
    sets: Vec<String>,
    path: Option<PathBuf>,
    base_dir: PathBuf,
    /// Whether the case passed `check` after the last override (None: not checked yet).
    valid: Option<bool>,
}

impl CaseCore {
    fn err(&self, py: Python<'_>, e: impl Into<Error>) -> PyErr {
        to_py_err(py, e.into(), self.path.as_deref(), &self.sets)
    }

    fn resolved(&self, py: Python<'_>) -> PyResult<toml::Value> {
        sinterdem::kinds::resolve(&self.value, &self.sets).map_err(|e| self.err(py, e))
    }

    /// `sinterdem check` of the case with `sets` (its warnings are not repeated here: `check()`
    /// and the run give them).
    fn validate(&self, py: Python<'_>, sets: &[String]) -> Result<(), Error> {
        let (value, base) = (&self.value, &self.base_dir);
        py.detach(|| {
            tracing::subscriber::with_default(tracing::subscriber::NoSubscriber::default(), || {
                shielded(|| sinterdem::calibrate::check_file(value, sets, base).map(|_| ()))
            })
        })
    }
}

/// Whether a configuration error concerns `key` (names it, or a part of it, as serde names an
/// unknown field or variant).
fn concerns(e: &Error, key: &str) -> bool {
    let Error::Config(ce) = e else { return false };
    let k = config::messages::normalise_key(key);
    if ce.key().is_some_and(|n| config::messages::normalise_key(n) == k) {
        return true;
    }
    let text = ce.to_string();
    text.contains(&k) || k.split('.').filter(|p| p.parse::<usize>().is_err()).any(|p| text.contains(&format!("`{p}`")) || text.contains(&format!("\"{p}\"")))
}

fn base_of(path: &Path) -> PathBuf {
    path.parent().filter(|p| !p.as_os_str().is_empty()).map(Path::to_path_buf).unwrap_or_else(|| PathBuf::from("."))
}

/// `sinterdem.run` and `Simulation` replace an earlier run's outputs in `out` (the command line's
/// `--force`): a notebook re-executes its cells into the same directory (docs/decisions.md
/// "Clean output directories"). The outputs are never a mix of two runs either way.
const PY_FORCE: bool = true;

/// The run commands of a case (`sinterdem run`, `sinterdem rve`): one signature.
type RunCommand = fn(&toml::Value, &[String], &Path, &sinterdem::kinds::RunParams) -> Result<sinterdem::kinds::RunSummary, Error>;

impl CaseCore {
    /// Runs `command` into `out` with the GIL released (module doc of `run`).
    fn run_command(
        &self,
        py: Python<'_>,
        out: PathBuf,
        progress: bool,
        threads: Option<i128>,
        poll: Option<Py<PyAny>>,
        command: RunCommand,
    ) -> PyResult<(String, f64, bool)> {
        let params = sinterdem::kinds::RunParams { base_dir: self.base_dir.clone(), progress, echo_log: true, plots: true, wall_limit: None, force: PY_FORCE };
        // a compact case loaded from a file without a title is titled by the file's stem
        let titled = match &self.path {
            Some(p) => sinterdem::kinds::title_from_file(self.value.clone(), p),
            None => self.value.clone(),
        };
        let (value, sets) = (&titled, &self.sets);
        let watch = Watch::new(poll);
        let scope = watch.scope.clone();
        let threads = threads.map(check_threads).transpose().map_err(|e| self.err(py, e))?;
        let res = watch.detached(py, || -> Result<sinterdem::kinds::RunSummary, Error> {
            match threads {
                Some(n) => {
                    let pool =
                        rayon::ThreadPoolBuilder::new().num_threads(n).build().map_err(|e| Error::from(ConfigError::invalid(format!("threads = {n}: {e}"))))?;
                    // the run goes to the pool (in this call's stop scope); this thread (the one
                    // whose poll sees Python's signal handlers) asks for a stop request every
                    // poll interval until it ends
                    std::thread::scope(|s| {
                        let worker = s.spawn(|| {
                            pool.install(|| {
                                let _in = scope.enter();
                                shielded(|| command(value, sets, &out, &params))
                            })
                        });
                        while !worker.is_finished() {
                            sinterdem::interrupt::requested();
                            std::thread::sleep(std::time::Duration::from_secs_f64(0.2 * sinterdem::interrupt::POLL_INTERVAL));
                        }
                        worker.join().unwrap_or_else(|_| Err(internal_error("the run's thread ended without a result")))
                    })
                }
                None => command(value, sets, &out, &params),
            }
        });
        let s = res.map_err(|e| self.err(py, e))?;
        Ok((s.kind.name().to_string(), s.wall_seconds, watch.interrupted()))
    }
}

#[pymethods]
impl CaseCore {
    /// Reads a case file (as `sinterdem run FILE` does: includes expanded relative to its folder).
    #[staticmethod]
    fn load(py: Python<'_>, path: PathBuf) -> PyResult<CaseCore> {
        let value = config::load_case(&path, &[]).map_err(|e| to_py_err(py, e, Some(&path), &[]))?;
        Ok(CaseCore { value, sets: vec![], base_dir: base_of(&path), path: Some(path), valid: None })
    }

    /// Parses case text; relative paths in it start at `base_dir`.
    #[staticmethod]
    fn from_toml(py: Python<'_>, text: &str, base_dir: PathBuf) -> PyResult<CaseCore> {
        let mut value = config::parse_case_str(text, "<case text>").map_err(|e| to_py_err(py, e.into(), None, &[]))?;
        config::expand_includes(&mut value, &base_dir).map_err(|e| to_py_err(py, e.into(), None, &[]))?;
        config::apply_aliases(&mut value).map_err(|e| to_py_err(py, e.into(), None, &[]))?;
        Ok(CaseCore { value, sets: vec![], path: None, base_dir, valid: None })
    }

    /// A case from a dict (nested dicts are tables, lists of dicts arrays of tables).
    #[staticmethod]
    fn from_dict(py: Python<'_>, d: &Bound<'_, PyDict>, base_dir: PathBuf) -> PyResult<CaseCore> {
        let mut value = py_to_toml(d.as_any())?;
        config::expand_includes(&mut value, &base_dir).map_err(|e| to_py_err(py, e.into(), None, &[]))?;
        config::apply_aliases(&mut value).map_err(|e| to_py_err(py, e.into(), None, &[]))?;
        Ok(CaseCore { value, sets: vec![], path: None, base_dir, valid: None })
    }

    /// `case[key] = value`: one `--set key=value` override (a dict replaces the whole table),
    /// validated at once as `sinterdem check` validates the case (keys, types, ranges, scene):
    /// an error the assignment causes is raised here and the override is not kept. An error the
    /// case had before and that the assignment does not concern (a case being built key by key)
    /// waits for `check()` or the run. Returns the override as the command line would spell it.
    fn set(&mut self, py: Python<'_>, key: &str, value: &Bound<'_, PyAny>) -> PyResult<String> {
        // errors of the value name the key assigned (a whole number beyond 64 bits, nesting)
        let v = py_to_toml_at(value, key, 0)?;
        let assignment = format!("{key}={v}");
        let mut sets = self.sets.clone();
        sets.push(assignment.clone());
        sinterdem::kinds::resolve(&self.value, &sets).map_err(|e| to_py_err(py, e.into(), self.path.as_deref(), &sets))?;
        match self.validate(py, &sets) {
            Ok(()) => self.valid = Some(true),
            Err(e) => {
                let before = match self.valid {
                    Some(b) => b,
                    None => self.validate(py, &self.sets).is_ok(),
                };
                if before || concerns(&e, key) {
                    return Err(to_py_err(py, e, self.path.as_deref(), &sets));
                }
                self.valid = Some(false);
            }
        }
        self.sets = sets;
        Ok(assignment)
    }

    /// The value at a dotted key path of the case with its overrides (KeyError if absent).
    fn get<'py>(&self, py: Python<'py>, key: &str) -> PyResult<Bound<'py, PyAny>> {
        let v = self.resolved(py)?;
        let path = config::alias_of(&v, key);
        let mut cur = &v;
        for k in path.split('.') {
            let next = match cur {
                toml::Value::Table(t) => t.get(k),
                toml::Value::Array(a) => k.parse::<usize>().ok().and_then(|i| a.get(i)),
                _ => None,
            };
            cur = next.ok_or_else(|| PyKeyError::new_err(key.to_string()))?;
        }
        toml_to_py(py, cur)
    }

    /// The case with its overrides, as TOML text.
    fn to_toml(&self, py: Python<'_>) -> PyResult<String> {
        let v = self.resolved(py)?;
        toml::to_string(&v).map_err(|e| self.err(py, ConfigError::invalid(format!("case cannot be written as TOML: {e}"))))
    }

    /// The case with its overrides, as a dict.
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let v = self.resolved(py)?;
        toml_to_py(py, &v)
    }

    /// `sinterdem check`: validates the case (or calibration file) without running it.
    fn check(&self, py: Python<'_>) -> PyResult<String> {
        let (value, sets, base) = (self.value.clone(), self.sets.clone(), self.base_dir.clone());
        py.detach(move || shielded(|| sinterdem::calibrate::check_file(&value, &sets, &base))).map_err(|e| self.err(py, e))
    }

    /// `sinterdem run`: runs the case into `out` through `sinterdem::kinds::run` with the GIL
    /// released; returns (kind, wall seconds, interrupted). `poll(t, end)` (optional) is called
    /// with the GIL about every 50 ms (Jupyter's progress line); Ctrl-C (Python's SIGINT
    /// handler) stops the run after its current step with its outputs written (with `threads`
    /// too: the run then computes on a pool thread while this one watches), and `interrupted`
    /// is True (the Python layer raises KeyboardInterrupt).
    #[pyo3(signature = (out, progress=true, threads=None, poll=None))]
    fn run(&self, py: Python<'_>, out: PathBuf, progress: bool, threads: Option<i128>, poll: Option<Py<PyAny>>) -> PyResult<(String, f64, bool)> {
        self.run_command(py, out, progress, threads, poll, sinterdem::kinds::run)
    }

    /// `sinterdem rve`: the constitutive data of a periodic compact (docs/rve.md) into `out`
    /// through `sinterdem::kinds::rve::run`, as `run` does (GIL released, Ctrl-C, threads);
    /// returns (kind, wall seconds, interrupted).
    #[pyo3(signature = (out, progress=true, threads=None, poll=None))]
    fn rve(&self, py: Python<'_>, out: PathBuf, progress: bool, threads: Option<i128>, poll: Option<Py<PyAny>>) -> PyResult<(String, f64, bool)> {
        self.run_command(py, out, progress, threads, poll, sinterdem::kinds::rve::run)
    }

    /// `sinterdem conductivity`: the steady effective conductivity of the packing, as the JSON
    /// text the command prints (the Python layer parses it: the same numbers, bit for bit).
    fn conductivity(&self, py: Python<'_>) -> PyResult<String> {
        let value = self.resolved(py)?;
        let base = self.base_dir.clone();
        let v = py.detach(move || shielded(|| sinterdem::kinds::conductivity::run_case(value, &base))).map_err(|e| self.err(py, e))?;
        Ok(serde_json::to_string_pretty(&v).unwrap_or_default())
    }

    /// A preset of the materials library (`sinterdem.materials()`) as a `[[materials]]` table
    /// to edit: its thermal and elastic values and the name of its bundled diffusion data.
    #[staticmethod]
    fn preset_material<'py>(py: Python<'py>, name: &str) -> PyResult<Bound<'py, PyAny>> {
        let m = sinterdem::material::preset(name).ok_or_else(|| {
            to_py_err(
                py,
                ConfigError::invalid(format!("preset_material(\"{name}\"): unknown preset ({})", sinterdem::models::diffusion7::library::names())).into(),
                None,
                &[],
            )
        })?;
        let mut v = toml::Value::try_from(&m).map_err(|e| to_py_err(py, ConfigError::invalid(format!("material {name}: {e}")).into(), None, &[]))?;
        if let Some(t) = v.as_table_mut() {
            t.remove("diffusion_data");
        }
        toml_to_py(py, &v)
    }

    /// The overrides given so far, as `--set` arguments.
    #[getter]
    fn overrides(&self) -> Vec<String> {
        self.sets.clone()
    }

    /// The case file, if the case was loaded from one.
    #[getter]
    fn path(&self) -> Option<PathBuf> {
        self.path.clone()
    }

    /// The folder relative paths of the case start from.
    #[getter]
    fn base_dir(&self) -> PathBuf {
        self.base_dir.clone()
    }

    fn copy(&self) -> CaseCore {
        self.clone()
    }
}

/// Watches a long call made with the GIL released: while it runs, every ~50 ms
/// (`sinterdem::interrupt::POLL_INTERVAL`) it takes the GIL, lets Python run its signal handlers
/// (Ctrl-C raises KeyboardInterrupt there: kept, and the run is asked to stop after its current
/// step) and calls the progress callback with (t, end) [s].
struct Watch {
    poll: Option<Py<PyAny>>,
    error: std::sync::Arc<std::sync::Mutex<Option<PyErr>>>,
    scope: sinterdem::interrupt::Scope,
}

/// Moves a value into a closure run with the GIL released on this same thread (the stepping
/// object is not `Send`; `detach` runs the closure synchronously, on the calling thread).
struct SameThread<T>(T);
// SAFETY: `Python::detach` runs its closure on the calling thread before returning; the value
// never reaches another thread.
unsafe impl<T> Send for SameThread<T> {}
impl<T> SameThread<T> {
    fn get(self) -> T {
        self.0
    }
}

impl Watch {
    fn new(poll: Option<Py<PyAny>>) -> Watch {
        Watch { poll, error: Default::default(), scope: sinterdem::interrupt::Scope::new() }
    }

    /// Runs `f` with the GIL released and this watch polled, in a stop scope of its own
    /// ([`sinterdem::interrupt::Scope`]): Ctrl-C stops this call only, not the calls of other
    /// threads (issue 38 item 3). A panic in `f` is an error (`internal_error`), never a
    /// `PanicException`.
    fn detached<T>(&self, py: Python<'_>, f: impl FnOnce() -> Result<T, Error>) -> Result<T, Error> {
        let poll = self.poll.as_ref().map(|p| p.clone_ref(py));
        let error = self.error.clone();
        let hook = move || -> bool {
            Python::attach(|py| {
                if let Err(e) = py.check_signals() {
                    *error.lock().unwrap_or_else(|e| e.into_inner()) = Some(e);
                    return true;
                }
                if let (Some(cb), Some((t, end))) = (poll.as_ref(), sinterdem::io::progress::latest()) {
                    let _ = cb.call1(py, (t, end));
                }
                false
            })
        };
        let _scope = self.scope.enter();
        let _guard = sinterdem::interrupt::set_poll(Box::new(hook));
        let f = SameThread(f);
        py.detach(move || SameThread(shielded(f.get()))).get()
    }

    /// Whether Ctrl-C (or another signal handler's exception) stopped the call.
    fn interrupted(&self) -> bool {
        self.error.lock().unwrap_or_else(|e| e.into_inner()).is_some()
    }

    /// The exception a signal handler raised during the call, if any.
    fn take_error(&self) -> Option<PyErr> {
        self.error.lock().unwrap_or_else(|e| e.into_inner()).take()
    }
}

/// A heat, compact or explicit_sinter run one step at a time (`sinterdem.Simulation`):
/// `sinterdem::kinds::Stepper`.
#[pyclass(module = "sinterdem._native", unsendable)]
struct SimulationCore {
    stepper: Option<sinterdem::kinds::Stepper>,
    case: CaseCore,
    kind: String,
    poll: Option<Py<PyAny>>,
    /// Why the stepper is gone before finish() (a model or internal error ended the run).
    broken: Option<String>,
    /// The state when a model error ended the run (the stepper is gone then): what `time`,
    /// `step_count`, `end`, `relative_density`, `shrinkage` and `stage` read afterwards.
    last: Option<LastState>,
}

/// The state of a run a model error ended: time [s], steps, end time [s], relative density [1],
/// shrinkage per axis [1], explicit_sinter stage.
#[derive(Clone)]
struct LastState {
    time: f64,
    steps: u64,
    end: f64,
    relative_density: Option<f64>,
    shrinkage: Option<[f64; 3]>,
    stage: Option<(String, f64, Option<f64>)>,
}

impl LastState {
    fn of(s: &sinterdem::kinds::Stepper) -> LastState {
        LastState {
            time: s.time(),
            steps: s.steps(),
            end: s.end(),
            relative_density: s.relative_density(),
            shrinkage: s.shrinkage(),
            stage: s.stage().map(|(st, p, ts)| (st.to_string(), p, ts)),
        }
    }
}

impl SimulationCore {
    /// A value of the live run, or of the state a model error left ([`LastState`]).
    fn read<T>(&mut self, live: impl FnOnce(&sinterdem::kinds::Stepper) -> T, last: impl FnOnce(&LastState) -> T) -> PyResult<T> {
        if self.stepper.is_none()
            && let Some(l) = &self.last
        {
            return Ok(last(l));
        }
        Ok(live(self.live()?))
    }

    fn live(&mut self) -> PyResult<&mut sinterdem::kinds::Stepper> {
        let why = self.broken.clone().unwrap_or_else(|| "finish() was called".into());
        self.stepper.as_mut().ok_or_else(|| pyo3::exceptions::PyRuntimeError::new_err(format!("the simulation is finished ({why})")))
    }

    /// Runs `f` on the stepper with the GIL released and Ctrl-C watched; a Ctrl-C stops the run
    /// (outputs written by `finish`) and is re-raised.
    fn call<T>(&mut self, py: Python<'_>, f: impl FnOnce(&mut sinterdem::kinds::Stepper) -> Result<T, Error>) -> PyResult<T> {
        let watch = Watch::new(self.poll.as_ref().map(|p| p.clone_ref(py)));
        let stepper = SameThread(self.live()?);
        let res = watch.detached(py, move || f(stepper.get()));
        if res.as_ref().err().is_some_and(is_internal) {
            // a panic left the run in an unknown state: it cannot go on, nor be summarised
            self.stepper = None;
            self.broken = Some("an internal error stopped it".into());
        }
        let res = res.map_err(|e| self.case.err(py, e));
        if let Some(e) = watch.take_error() {
            if let Some(s) = self.stepper.as_mut()
                && !s.done()
            {
                s.stop("interrupted").map_err(|e| self.case.err(py, e))?;
            }
            return Err(e);
        }
        // a model error ended the run in this call: its outputs are written now (summary.json
        // with completed = false and the error) and the error is raised here, by the step that
        // met it (issue 38 item 8), not by a later finish()
        if res.is_ok() && self.stepper.as_ref().is_some_and(|s| s.failed()) {
            let s = self.stepper.take().expect("checked above");
            self.last = Some(LastState::of(&s));
            let s = SameThread(s);
            self.broken = Some("a model error ended it".into());
            let end = py.detach(move || SameThread(shielded(move || s.get().finish()))).get();
            return Err(match end {
                Err(e) => self.case.err(py, e),
                Ok(_) => self.case.err(py, internal_error("the run failed but finish() reported no error")),
            });
        }
        res
    }
}

fn array<'py>(py: Python<'py>, v: Vec<f64>, cols: usize) -> PyResult<Bound<'py, PyAny>> {
    let n = v.len() / cols.max(1);
    let a = PyArray1::from_vec(py, v);
    Ok(if cols > 1 { a.reshape([n, cols])?.into_any() } else { a.into_any() })
}

fn int_array<'py>(py: Python<'py>, v: Vec<i64>, cols: usize) -> PyResult<Bound<'py, PyAny>> {
    let n = v.len() / cols.max(1);
    let a = PyArray1::from_vec(py, v);
    Ok(if cols > 1 { a.reshape([n, cols])?.into_any() } else { a.into_any() })
}

#[pymethods]
impl SimulationCore {
    /// Prepares the case and opens the outputs in `out` (writes those due at t = 0).
    #[new]
    #[pyo3(signature = (case, out, progress=true, poll=None))]
    fn new(py: Python<'_>, case: &CaseCore, out: PathBuf, progress: bool, poll: Option<Py<PyAny>>) -> PyResult<SimulationCore> {
        let params = sinterdem::kinds::RunParams { base_dir: case.base_dir.clone(), progress, echo_log: true, plots: true, wall_limit: None, force: PY_FORCE };
        let (value, sets) = (case.value.clone(), case.sets.clone());
        let res = py.detach(move || SameThread(shielded(|| sinterdem::kinds::Stepper::start(&value, &sets, &out, &params)))).get();
        let stepper = res.map_err(|e| case.err(py, e))?;
        Ok(SimulationCore { kind: stepper.kind().name().to_string(), stepper: Some(stepper), case: case.clone(), poll, broken: None, last: None })
    }

    /// One accepted step; returns whether the run goes on.
    fn step(&mut self, py: Python<'_>) -> PyResult<bool> {
        self.call(py, |s| s.step())
    }

    /// Steps until `to` [s] (the last step may pass it); returns whether the run goes on.
    fn advance(&mut self, py: Python<'_>, to: f64) -> PyResult<bool> {
        self.call(py, |s| s.advance(to))
    }

    /// Up to `n` steps, stopping early when the run ends; returns whether the run goes on.
    fn steps(&mut self, py: Python<'_>, n: u64) -> PyResult<bool> {
        self.call(py, |s| {
            for _ in 0..n {
                if !s.step()? {
                    return Ok(false);
                }
            }
            Ok(!s.done())
        })
    }

    #[getter]
    fn time(&mut self) -> PyResult<f64> {
        self.read(|s| s.time(), |l| l.time)
    }

    #[getter]
    fn step_count(&mut self) -> PyResult<u64> {
        self.read(|s| s.steps(), |l| l.steps)
    }

    #[getter]
    fn end(&mut self) -> PyResult<f64> {
        self.read(|s| s.end(), |l| l.end)
    }

    #[getter]
    fn done(&mut self) -> PyResult<bool> {
        Ok(self.live()?.done())
    }

    #[getter]
    fn kind(&self) -> String {
        self.kind.clone()
    }

    #[getter]
    fn relative_density(&mut self) -> PyResult<Option<f64>> {
        self.read(|s| s.relative_density(), |l| l.relative_density)
    }

    /// Shrinkage per axis now [1] (compact runs; None otherwise).
    #[getter]
    fn shrinkage(&mut self) -> PyResult<Option<[f64; 3]>> {
        self.read(|s| s.shrinkage(), |l| l.shrinkage)
    }

    /// explicit_sinter: (stage, pressure [Pa], sintering time of the branch in progress [s] or
    /// None); None for heat and compact runs.
    #[getter]
    fn stage(&mut self) -> PyResult<Option<(String, f64, Option<f64>)>> {
        self.read(|s| s.stage().map(|(s, p, ts)| (s.to_string(), p, ts)), |l| l.stage.clone())
    }

    /// The particles now: ids (N,) int64, positions (N, 3) m, radii (N,) m, temperatures (N,) K,
    /// displacements (N, 3) m (copies).
    fn particles<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let p = self.live()?.particles();
        let d = PyDict::new(py);
        d.set_item("ids", int_array(py, p.ids, 1)?)?;
        d.set_item("positions", array(py, p.positions, 3)?)?;
        d.set_item("radii", array(py, p.radii, 1)?)?;
        d.set_item("temperatures", array(py, p.temperatures, 1)?)?;
        d.set_item("displacements", array(py, p.displacements, 3)?)?;
        Ok(d)
    }

    /// The contacts now: pairs (M, 2) int64, neck_radii (M,) m, forces (M,) N (copies).
    fn contacts<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let c = self.live()?.contacts();
        let d = PyDict::new(py);
        d.set_item("pairs", int_array(py, c.pairs, 2)?)?;
        d.set_item("neck_radii", array(py, c.neck_radii, 1)?)?;
        d.set_item("forces", array(py, c.forces, 1)?)?;
        Ok(d)
    }

    /// Holds the furnace at `temperature` [K] from now on.
    fn set_furnace_temperature(&mut self, py: Python<'_>, temperature: f64) -> PyResult<()> {
        let r = self.live()?.set_furnace_temperature(temperature);
        r.map_err(|e| self.case.err(py, e))
    }

    /// Holds the applied stress at `stress` [Pa] from now on (compact with [load]).
    fn set_applied_stress(&mut self, py: Python<'_>, stress: f64) -> PyResult<()> {
        let r = self.live()?.set_applied_stress(stress);
        r.map_err(|e| self.case.err(py, e))
    }

    /// Ends the run early with `reason` as its stop_reason.
    fn stop(&mut self, py: Python<'_>, reason: &str) -> PyResult<()> {
        let r = self.live()?.stop(reason);
        r.map_err(|e| self.case.err(py, e))
    }

    /// Writes summary.json and the plots; returns the wall seconds. Idempotent: later calls do
    /// nothing and return None.
    fn finish(&mut self, py: Python<'_>) -> PyResult<Option<f64>> {
        let Some(s) = self.stepper.take() else { return Ok(None) };
        let s = SameThread(s);
        let res = py.detach(move || SameThread(shielded(move || s.get().finish()))).get();
        let summary = res.map_err(|e| self.case.err(py, e))?;
        Ok(Some(summary.wall_seconds))
    }

    /// Whether finish() was called.
    #[getter]
    fn finished(&self) -> bool {
        self.stepper.is_none()
    }
}

/// Reads a CSV written by sinterdem (one header line, units in the names; `#` lines before it are
/// comments, as in a packing file) into
/// (names, columns): float64 numpy arrays for numeric columns (parsed exactly, as Rust writes
/// them), lists of strings for the others.
#[pyfunction]
fn read_csv<'py>(py: Python<'py>, path: PathBuf) -> PyResult<(Vec<String>, Vec<Bound<'py, PyAny>>)> {
    let err = |m: String| to_py_err(py, sinterdem::error::IoError::new(&path, m).into(), None, &[]);
    let mut r = csv::ReaderBuilder::new().has_headers(true).comment(Some(b'#')).from_path(&path).map_err(|e| err(e.to_string()))?;
    let names: Vec<String> = r.headers().map_err(|e| err(e.to_string()))?.iter().map(str::to_string).collect();
    let mut cols: Vec<Vec<String>> = vec![Vec::new(); names.len()];
    for rec in r.records() {
        let rec = rec.map_err(|e| err(e.to_string()))?;
        for (i, c) in cols.iter_mut().enumerate() {
            c.push(rec.get(i).unwrap_or_default().to_string());
        }
    }
    let mut out = Vec::with_capacity(names.len());
    for c in cols {
        // counts (written as integers, docs/outputs.md) come back as int64
        let ints: Option<Vec<i64>> = if c.is_empty() { None } else { c.iter().map(|s| s.trim().parse::<i64>().ok()).collect() };
        if let Some(v) = ints {
            out.push(PyArray1::from_vec(py, v).into_any());
            continue;
        }
        let parsed: Option<Vec<f64>> = c.iter().map(|s| if s.is_empty() { Some(f64::NAN) } else { s.trim().parse::<f64>().ok() }).collect();
        out.push(match parsed {
            Some(v) => PyArray1::from_vec(py, v).into_any(),
            None => PyList::new(py, c)?.into_any(),
        });
    }
    Ok((names, out))
}

/// `sinterdem study FILE --out DIR [--engine] [--jobs]`; returns the study directory.
#[pyfunction]
#[pyo3(signature = (path, out, engine="local", jobs=None, progress=true, overrides=Vec::new()))]
fn study(py: Python<'_>, path: PathBuf, out: PathBuf, engine: &str, jobs: Option<i128>, progress: bool, overrides: Vec<String>) -> PyResult<PathBuf> {
    let engine = match engine {
        "local" => sinterdem::study::Engine::Local,
        "slurm" => sinterdem::study::Engine::Slurm,
        e => return Err(to_py_err(py, ConfigError::invalid(format!("engine = \"{e}\": expected \"local\" or \"slurm\"")).into(), None, &[])),
    };
    let jobs = jobs.map(|n| check_count("jobs", n)).transpose().map_err(|e| to_py_err(py, e, None, &[]))?;
    let opts = sinterdem::study::StudyOptions { engine, jobs, out: Some(out), wait: true, overrides, progress, ..Default::default() };
    let info = py.detach(|| shielded(|| sinterdem::study::run_study(&path, &opts, &mut |_| {}))).map_err(|e| to_py_err(py, e, Some(&path), &opts.overrides))?;
    Ok(info.dir)
}

/// `sinterdem calibrate FILE --out DIR`.
#[pyfunction]
#[pyo3(signature = (path, out, overrides=Vec::new(), quiet=true))]
fn calibrate(py: Python<'_>, path: PathBuf, out: PathBuf, overrides: Vec<String>, quiet: bool) -> PyResult<()> {
    py.detach(|| shielded(|| sinterdem::calibrate::run_file(&path, &overrides, &out, quiet, false, false)))
        .map_err(|e| to_py_err(py, e, Some(&path), &overrides))
}

/// Parses TOML text into a dict (no case semantics: for files sinterdem wrote, e.g. material.toml).
#[pyfunction]
fn parse_toml<'py>(py: Python<'py>, text: &str, name: &str) -> PyResult<Bound<'py, PyAny>> {
    let v = config::parse_case_str(text, name).map_err(|e| to_py_err(py, e.into(), None, &[]))?;
    toml_to_py(py, &v)
}

/// A dict as TOML text (no case semantics: for study and calibration files given as dicts).
#[pyfunction]
fn dump_toml(py: Python<'_>, d: &Bound<'_, PyDict>) -> PyResult<String> {
    let v = py_to_toml(d.as_any())?;
    toml::to_string(&v).map_err(|e| to_py_err(py, ConfigError::invalid(format!("cannot be written as TOML: {e}")).into(), None, &[]))
}

/// For the `sinterdem` console command (a process of its own): SIGINT and SIGTERM stop a run after
/// its current step with its outputs written (exit code 130 / 143), as the Rust binary does. Not for an interactive interpreter: it replaces Python's SIGINT handler.
#[pyfunction]
fn install_signal_handlers(py: Python<'_>) -> PyResult<()> {
    sinterdem::interrupt::install_handlers().map_err(|e| to_py_err(py, sinterdem::error::IoError::new("<signal handlers>", e.to_string()).into(), None, &[]))
}

/// The command line: `sinterdem.cli_main(["sinterdem", "run", …])` returns the exit code.
#[pyfunction]
fn cli_main(py: Python<'_>, args: Vec<String>) -> i32 {
    py.detach(move || match std::panic::catch_unwind(move || sinterdem::cli::main(args)) {
        Ok(code) => code,
        Err(_) => {
            let m = LAST_PANIC.lock().unwrap_or_else(|e| e.into_inner()).take().unwrap_or_else(|| "panic".into());
            eprintln!("error: internal error in sinterdem ({m}); this is a bug: please report it with the case that caused it");
            101
        }
    })
}

/// `threads = n` of a run: the command line's `--threads` bound ([`sinterdem::cli::check_threads`]:
/// 1 to 4 per available core, at least 16), so that Python and the CLI accept the same counts.
fn check_threads(n: i128) -> Result<usize, Error> {
    check_count("threads", n)
}

/// A thread or job count `n` given as `key`, bounded as the command line bounds it (any Python
/// int: -1 or 10**30 get the same range error as 0 or 10**6, not pyo3's OverflowError).
fn check_count(key: &str, n: i128) -> Result<usize, Error> {
    match usize::try_from(n) {
        Ok(u) if u >= 1 => Ok(sinterdem::cli::check_threads(key, u)?),
        _ => match sinterdem::cli::check_threads(key, 0) {
            Err(ConfigError::OutOfRange { key, range, unit, .. }) => Err(ConfigError::OutOfRange { key, value: n as f64, range, unit }.into()),
            other => Ok(other?),
        },
    }
}

/// The log lines and warnings of the library, kept for the Python layer (`sinterdem._logs`)
/// to pass to `logging` and `warnings` after each call: (level 10/20/30/40, line).
static LOG: std::sync::Mutex<Vec<(u8, String)>> = std::sync::Mutex::new(Vec::new());
/// Most lines kept between two drains (a caller that never drains loses the oldest).
const LOG_CAP: usize = 10_000;

/// Routes the library's `tracing` events (info and above) to [`LOG`] and a run's events to
/// its `log.txt` ([`sinterdem::logging::init_with_sink`]); once per process. Not at import:
/// the `sinterdem` console command (same package) installs the command line's own subscriber.
#[pyfunction]
fn capture_log() -> bool {
    static ONCE: std::sync::Once = std::sync::Once::new();
    let mut installed = false;
    ONCE.call_once(|| {
        installed = sinterdem::logging::init_with_sink(
            tracing::Level::INFO,
            Box::new(|level, line| {
                let lv = match level {
                    tracing::Level::ERROR => 40,
                    tracing::Level::WARN => 30,
                    tracing::Level::INFO => 20,
                    _ => 10,
                };
                let text = line.strip_prefix("warning: ").or_else(|| line.strip_prefix("error: ")).unwrap_or(line);
                let mut g = LOG.lock().unwrap_or_else(|e| e.into_inner());
                if g.len() >= LOG_CAP {
                    g.remove(0);
                }
                g.push((lv, text.to_string()));
            }),
        );
    });
    installed
}

/// The lines kept since the last call: [(level, text)].
#[pyfunction]
fn take_log() -> Vec<(u8, String)> {
    std::mem::take(&mut *LOG.lock().unwrap_or_else(|e| e.into_inner()))
}

/// `sinterdem neck`: the JSON object the command prints, as text (parsed by the Python layer).
#[pyfunction]
#[pyo3(signature = (r1, r2, overlap, kappa, kappa2=None, conductance="fe_fit".to_string(), factor=1.064, contact_conductance=None))]
#[allow(clippy::too_many_arguments)]
fn neck(
    py: Python<'_>,
    r1: f64,
    r2: f64,
    overlap: f64,
    kappa: f64,
    kappa2: Option<f64>,
    conductance: String,
    factor: f64,
    contact_conductance: Option<f64>,
) -> PyResult<String> {
    let a = sinterdem::cli::NeckArgs { r1, r2, overlap, kappa, kappa2, conductance, factor, contact_conductance };
    let v = shielded(|| sinterdem::cli::neck_report(&a)).map_err(|e| to_py_err(py, e, None, &[]))?;
    Ok(serde_json::to_string_pretty(&v).unwrap_or_default())
}

/// The bundled materials library (docs/materials.md), one dict per preset (SI units).
#[pyfunction]
fn materials<'py>(py: Python<'py>) -> PyResult<Vec<Bound<'py, PyDict>>> {
    use sinterdem::models::diffusion7::library;
    let mut rows = Vec::new();
    for e in library::entries() {
        let d = PyDict::new(py);
        d.set_item("name", &e.name)?;
        d.set_item("description", &e.description)?;
        d.set_item("density_kg_per_m3", e.preset.density)?;
        d.set_item("heat_capacity_J_per_kgK", e.preset.heat_capacity)?;
        d.set_item("conductivity_W_per_mK", e.preset.conductivity)?;
        d.set_item("properties_at_K", e.preset.temperature)?;
        d.set_item("young_modulus_Pa", e.preset_young_modulus())?;
        d.set_item("poisson_ratio", e.preset_poisson_ratio())?;
        d.set_item("calibrated_min_temperature_K", e.calibrated_min_temperature)?;
        d.set_item("calibrated_max_temperature_K", e.calibrated_max_temperature)?;
        d.set_item("melting_temperature_K", e.melting_temperature)?;
        d.set_item("phases", e.phases.len())?;
        d.set_item("temperature_tables", e.tables.is_some())?;
        d.set_item("unmeasured", e.unmeasured.join(", "))?;
        d.set_item("source", &e.source)?;
        rows.push(d);
    }
    Ok(rows)
}

/// The allowed range and unit of a numeric case key (`sinterdem keys`), e.g.
/// `key_range("pair.radius")`; None for keys without a range.
#[pyfunction]
fn key_range(key: &str) -> Option<(String, String, String)> {
    let k = config::messages::normalise_key(key);
    let k = k.split(' ').next().unwrap_or_default().to_string();
    sinterdem::config::ranges::lookup_in(&sinterdem::calibrate::every_table(), &k).map(|r| (r.describe(), r.unit.to_string(), r.meaning.to_string()))
}

#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    quiet_panics();
    m.add_function(wrap_pyfunction!(capture_log, m)?)?;
    m.add_function(wrap_pyfunction!(take_log, m)?)?;
    m.add_function(wrap_pyfunction!(neck, m)?)?;
    m.add_function(wrap_pyfunction!(materials, m)?)?;
    m.add_function(wrap_pyfunction!(key_range, m)?)?;
    m.add_class::<CaseCore>()?;
    m.add_class::<SimulationCore>()?;
    m.add_function(wrap_pyfunction!(read_csv, m)?)?;
    m.add_function(wrap_pyfunction!(study, m)?)?;
    m.add_function(wrap_pyfunction!(calibrate, m)?)?;
    m.add_function(wrap_pyfunction!(cli_main, m)?)?;
    m.add_function(wrap_pyfunction!(install_signal_handlers, m)?)?;
    m.add_function(wrap_pyfunction!(parse_toml, m)?)?;
    m.add_function(wrap_pyfunction!(dump_toml, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    // whether this build writes HDF5 (H5MD) output: built with `--features h5` (docs/python.md "Install")
    m.add("HDF5", cfg!(feature = "h5"))?;
    Ok(())
}
