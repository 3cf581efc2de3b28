//! The shared line-plot facility, in two halves: a plain [`PlotSpec`] that holds every decision
//! (title, subtitle, axis labels with units, axis ranges, tick labels, per-series colour, line
//! style and marker shape and where the markers sit) and a renderer that draws a spec with the
//! `plotters` crate as PNG and SVG ([`Plot::save_png`] writes both). The decisions are tested on
//! the spec; the renderer only draws it. Labels use DejaVu Sans, embedded in the binary
//! (`assets/fonts/DejaVuSans.ttf`, licence in `assets/fonts/LICENSE-DejaVu.txt`), so no system
//! fonts are needed.
//!
//! Every series is told apart by colour, line style (solid, dashed, dotted, dash-dot) and marker
//! shape; a line carries a few markers at positions staggered per series, so two curves that lie
//! on top of each other both stay visible (docs/outputs.md "Plots", docs/decisions.md).
//!
//! ```no_run
//! use sinterdem::plot::{Plot, Series};
//! let mut p = Plot::new("Neck growth").subtitle("copper, 2 × 50 µm").labels("time [s]", "neck radius / particle radius").log_x(true);
//! p.add(Series::new("copper", vec![(1.0, 0.1), (10.0, 0.14), (100.0, 0.21)]));
//! p.save_png(std::path::Path::new("neck.png")).unwrap(); // neck.png and neck.svg
//! ```

use crate::error::IoError;
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use std::path::Path;

/// How a series' line is drawn. Patterns are on/off lengths in pixels at the 640-pixel reference
/// height, drawn with round caps (a dot is a dash of almost zero length).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LineStyle {
    Solid,
    Dashed,
    Dotted,
    DashDot,
}

impl LineStyle {
    /// The order in which series receive styles.
    pub const CYCLE: [LineStyle; 4] = [LineStyle::Solid, LineStyle::Dashed, LineStyle::Dotted, LineStyle::DashDot];

    /// On/off lengths [px at 640 px height]; empty: solid.
    pub fn pattern(self) -> &'static [f64] {
        match self {
            LineStyle::Solid => &[],
            LineStyle::Dashed => &[10.0, 9.0],
            LineStyle::Dotted => &[0.5, 7.0],
            LineStyle::DashDot => &[12.0, 8.0, 0.5, 8.0],
        }
    }

    /// The SVG `stroke-dasharray` value at `scale` (None: solid).
    pub fn svg_dasharray(self, scale: f64) -> Option<String> {
        let p = self.pattern();
        (!p.is_empty()).then(|| p.iter().map(|v| tick_label((v * scale * 10.0).round() / 10.0)).collect::<Vec<_>>().join(","))
    }
}

/// A marker shape; `Open*` shapes are white inside with a coloured outline.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Marker {
    Circle,
    Square,
    Triangle,
    Diamond,
    OpenCircle,
    OpenSquare,
    OpenTriangle,
    OpenDiamond,
}

impl Marker {
    /// The order in which series receive marker shapes.
    pub const CYCLE: [Marker; 8] =
        [Marker::Circle, Marker::Square, Marker::Triangle, Marker::Diamond, Marker::OpenCircle, Marker::OpenSquare, Marker::OpenTriangle, Marker::OpenDiamond];
}

/// Where a series' markers sit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MarkerPlacement {
    /// No markers.
    None,
    /// At every data point.
    Every,
    /// `count` markers along the drawn line at arc-length fractions (j + phase)/count,
    /// j = 0…count−1: series sharing a plot get different phases, so overlapping curves show all
    /// their markers.
    Staggered { phase: f64, count: usize },
}

/// One named curve, as the caller describes it ([`Plot::spec`] turns it into a [`SeriesSpec`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    pub name: String,
    /// (x, y) points in drawing order; non-finite points (and non-positive ones on a log axis) are
    /// skipped and break the line.
    pub points: Vec<(f64, f64)>,
    /// Draw a marker at every point (otherwise a line gets a few staggered markers).
    pub markers: bool,
    /// Connect the points with a line.
    pub line: bool,
    /// Half-widths of vertical error bars, one per point (empty: none).
    pub error_bars: Vec<f64>,
    /// Line style (None: from the series' place, [`LineStyle::CYCLE`]).
    pub style: Option<LineStyle>,
    /// Marker shape (None: from the series' place, [`Marker::CYCLE`]).
    pub marker: Option<Marker>,
    /// No markers at all (a histogram).
    pub plain: bool,
    /// A reference line (a band, a ±2σ limit): dark grey, dashed, no markers; does not take a
    /// colour, style or marker from the cycles.
    pub reference: bool,
    /// Drawn in the colour of the k-th (non-reference) series, e.g. a fit in its data's colour
    /// ([`Series::colour_of`]); None: its own colour from the palette.
    pub colour_of: Option<usize>,
}

impl Series {
    /// A line (with a few staggered markers).
    pub fn new(name: impl Into<String>, points: Vec<(f64, f64)>) -> Series {
        Series {
            name: name.into(),
            points,
            markers: false,
            line: true,
            error_bars: Vec::new(),
            style: None,
            marker: None,
            plain: false,
            reference: false,
            colour_of: None,
        }
    }

    /// Drawn in the colour of the `k`-th series of the plot (reference lines not counted): a fit
    /// line in the colour of the data it fits (issue 39: `constitutive.png` coloured its fits
    /// unlike their data). Its line style and markers stay its own, and its colour differs from
    /// that series' by a few units of blue (invisible), so that every series keeps a colour of
    /// its own (the SVG dash arrays are keyed by colour).
    pub fn colour_of(mut self, k: usize) -> Series {
        self.colour_of = Some(k);
        self
    }

    /// A marker at every point.
    pub fn with_markers(mut self) -> Series {
        self.markers = true;
        self
    }

    /// Vertical error bars y ± e, one half-width per point (and markers).
    pub fn with_error_bars(mut self, half_widths: Vec<f64>) -> Series {
        self.error_bars = half_widths;
        self.markers = true;
        self
    }

    /// Markers only, no connecting line.
    pub fn points_only(mut self) -> Series {
        self.line = false;
        self.markers = true;
        self
    }

    /// A chosen line style.
    pub fn style(mut self, s: LineStyle) -> Series {
        self.style = Some(s);
        self
    }

    /// A chosen marker shape.
    pub fn marker(mut self, m: Marker) -> Series {
        self.marker = Some(m);
        self
    }

    /// No markers (a histogram outline).
    pub fn plain(mut self) -> Series {
        self.plain = true;
        self.markers = false;
        self
    }

    /// A reference line: dark grey, dashed, no markers.
    pub fn reference(mut self) -> Series {
        self.reference = true;
        self.plain = true;
        self.markers = false;
        self
    }
}

/// A line plot as the caller builds it.
#[derive(Debug, Clone, PartialEq)]
pub struct Plot {
    pub title: String,
    /// The second line under the title (the case and its key settings).
    pub subtitle: String,
    pub x_label: String,
    pub y_label: String,
    pub log_x: bool,
    pub log_y: bool,
    /// The axis range includes zero (a linear axis whose honest scale starts at zero).
    pub x_zero: bool,
    pub y_zero: bool,
    /// Named tick positions on x (experiment ids); empty: numeric ticks.
    pub x_ticks: Vec<(f64, String)>,
    /// Image size in pixels.
    pub width: u32,
    pub height: u32,
    pub series: Vec<Series>,
}

/// One axis of a [`PlotSpec`].
#[derive(Debug, Clone, PartialEq)]
pub struct AxisSpec {
    /// The label with its unit, `temperature [K]`.
    pub label: String,
    pub log: bool,
    /// The drawn range (data, padding and zero included).
    pub range: (f64, f64),
    /// Named ticks (empty: numeric ticks from [`tick_label`]).
    pub ticks: Vec<(f64, String)>,
}

/// One series of a [`PlotSpec`]: every drawing decision made.
#[derive(Debug, Clone, PartialEq)]
pub struct SeriesSpec {
    pub name: String,
    pub colour: [u8; 3],
    /// None: no line.
    pub line: Option<LineStyle>,
    /// None: no markers.
    pub marker: Option<Marker>,
    pub placement: MarkerPlacement,
    pub points: Vec<(f64, f64)>,
    pub error_bars: Vec<f64>,
}

/// Everything a plot shows, decided; [`render_spec`] draws it.
#[derive(Debug, Clone, PartialEq)]
pub struct PlotSpec {
    pub title: String,
    pub subtitle: String,
    pub x: AxisSpec,
    pub y: AxisSpec,
    pub series: Vec<SeriesSpec>,
    /// A legend (two or more named series).
    pub legend: bool,
    pub width: u32,
    pub height: u32,
}

type Rgb = [u8; 3];

const PALETTE: [Rgb; 10] = [
    [31, 119, 180],
    [214, 39, 40],
    [44, 160, 44],
    [255, 127, 14],
    [148, 103, 189],
    [140, 86, 75],
    [227, 119, 194],
    [127, 127, 127],
    [188, 189, 34],
    [23, 190, 207],
];

/// The colour of reference lines (not in the palette).
const REFERENCE: Rgb = [80, 80, 80];

/// Markers along a line (staggered placement).
const STAGGERED_MARKERS: usize = 8;

/// The colour of the k-th series: the palette, darkened on each further pass, so every series of
/// a plot has its own colour (the SVG dash arrays are keyed by it).
fn colour(k: usize) -> Rgb {
    let c = PALETTE[k % PALETTE.len()];
    let f = 1.0 - 0.25 * (k / PALETTE.len()).min(3) as f64;
    c.map(|v| (v as f64 * f).round() as u8)
}

/// `c` moved by 1 to 8 units of blue (by `i`, the series' place): the colour of another series
/// for the eye, a different one for the SVG dash keys ([`Series::colour_of`]).
fn shade(c: Rgb, i: usize) -> Rgb {
    let d = 1 + (i % 8) as u8;
    [c[0], c[1], if c[2] >= 128 { c[2] - d } else { c[2] + d }]
}

/// The embedded font, registered once as plotters' "sans-serif".
fn font() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        let bytes: &'static [u8] = include_bytes!("../../assets/fonts/DejaVuSans.ttf");
        let _ = plotters::style::register_font("sans-serif", FontStyle::Normal, bytes);
    });
}

/// A display unit: a value in it is the SI value / `factor`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Unit {
    pub name: &'static str,
    pub factor: f64,
}

impl Unit {
    /// The SI value `v` in this unit.
    pub fn of(&self, v: f64) -> f64 {
        v / self.factor
    }

    /// `(x, y)` points with x [SI] converted to this unit.
    pub fn x(&self, pts: Vec<(f64, f64)>) -> Vec<(f64, f64)> {
        pts.into_iter().map(|(x, y)| (x / self.factor, y)).collect()
    }
}

/// The unit a time axis reads best in, from the largest time shown `span` [s]: µs below 1 ms,
/// ms below 1 s, s below 5 min, min below 5 h, else h. A log axis spans decades and stays in s.
pub fn time_unit(span: f64, log: bool) -> Unit {
    let a = span.abs();
    if log || !a.is_finite() {
        Unit { name: "s", factor: 1.0 }
    } else if a < 1e-3 {
        Unit { name: "µs", factor: 1e-6 }
    } else if a < 1.0 {
        Unit { name: "ms", factor: 1e-3 }
    } else if a < 300.0 {
        Unit { name: "s", factor: 1.0 }
    } else if a < 5.0 * 3600.0 {
        Unit { name: "min", factor: 60.0 }
    } else {
        Unit { name: "h", factor: 3600.0 }
    }
}

/// The unit a length axis reads best in, from the largest length shown `span` [m]: nm below
/// 1 µm, µm below 1 mm, mm below 1 m, else m.
pub fn length_unit(span: f64) -> Unit {
    let a = span.abs();
    if !a.is_finite() || a >= 1.0 {
        Unit { name: "m", factor: 1.0 }
    } else if a < 1e-6 {
        Unit { name: "nm", factor: 1e-9 }
    } else if a < 1e-3 {
        Unit { name: "µm", factor: 1e-6 }
    } else {
        Unit { name: "mm", factor: 1e-3 }
    }
}

/// A time as it reads in a title: `45 s`, `83.3 min`, `3.5 h`.
pub fn fmt_time(t: f64) -> String {
    let u = time_unit(t, false);
    format!("{} {}", tick_label((u.of(t) * 10.0).round() / 10.0), u.name)
}

/// A length as it reads in a title: `33.3 µm`.
pub fn fmt_length(l: f64) -> String {
    let u = length_unit(l);
    format!("{} {}", tick_label((u.of(l) * 10.0).round() / 10.0), u.name)
}

/// A tick label: at most 4 significant digits, plain for 1e-3 ≤ |v| < 1e5, else `2.5e-5`.
pub fn tick_label(v: f64) -> String {
    tick_label_on(v, v.abs())
}

/// A tick label on an axis whose largest |value| is `axis_max`: every tick of an axis that reaches
/// 1e5 in the `2.5e5` form, so that 5e4 does not read `50000` beside `1e5` (as [`tick_label`] else).
pub fn tick_label_on(v: f64, axis_max: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return if v == 0.0 { "0".into() } else { format!("{v}") };
    }
    let trim = |s: String| if s.contains('.') { s.trim_end_matches('0').trim_end_matches('.').to_string() } else { s };
    let a = v.abs();
    if (1e-3..1e5).contains(&a) && axis_max < 1e5 {
        let decimals = (3 - a.log10().floor() as i32).max(0) as usize;
        trim(format!("{v:.decimals$}"))
    } else {
        let e = a.log10().floor() as i32;
        let m = v / 10f64.powi(e);
        let (m, e) = if (m.abs() * 1000.0).round() >= 10000.0 { (m / 10.0, e + 1) } else { (m, e) };
        format!("{}e{e}", trim(format!("{m:.3}")))
    }
}

/// The most decades a log axis spans (points further below its top are left out of the range).
const LOG_DECADES: f64 = 40.0;

/// Plot-area range of the points: x exactly the data, y padded by 4 % (a decade fraction on a log axis).
fn range(lo: f64, hi: f64, log: bool, pad: f64) -> (f64, f64) {
    if !(lo.is_finite() && hi.is_finite()) {
        return if log { (1.0, 10.0) } else { (0.0, 1.0) };
    }
    if log {
        // at most LOG_DECADES decades, none below 1e-300: the tick search of a log axis over a
        // range reaching subnormal numbers never ends (issue 38: an output time of 1e-310 s)
        let b = hi.log10().min(300.0);
        let a = lo.log10().max(b - LOG_DECADES).max(-300.0);
        let (a, b) = if b - a < 1e-9 { (a - 0.5, b + 0.5) } else { (a, b) };
        let p = pad * (b - a);
        let (a, b) = (a - p, b + p);
        // plotters labels the powers of ten inside a log axis (and points between them only when
        // there are many): a range holding fewer than two had one tick label or none (issue 39,
        // constitutive.png). It is widened to the decades around it, a hair beyond them so that
        // both end powers are inside.
        if b.floor() - a.ceil() < 1.0 {
            return (10f64.powf(a.floor()) * (1.0 - 1e-9), 10f64.powf(b.ceil()) * (1.0 + 1e-9));
        }
        (10f64.powf(a), 10f64.powf(b))
    } else {
        let w = hi - lo;
        if w <= 1e-12 * hi.abs().max(lo.abs()).max(1e-300) {
            let d = if hi == 0.0 { 1.0 } else { 0.05 * hi.abs() };
            (lo - d, hi + d)
        } else {
            (lo - pad * w, hi + pad * w)
        }
    }
}

type DrawResult<E> = Result<(), DrawingAreaErrorKind<E>>;

impl Plot {
    /// An empty 960×640 plot with linear axes.
    pub fn new(title: impl Into<String>) -> Plot {
        Plot {
            title: title.into(),
            subtitle: String::new(),
            x_label: String::new(),
            y_label: String::new(),
            log_x: false,
            log_y: false,
            x_zero: false,
            y_zero: false,
            x_ticks: Vec::new(),
            width: 960,
            height: 640,
            series: Vec::new(),
        }
    }

    /// The subtitle (the case and its key settings).
    pub fn subtitle(mut self, s: impl Into<String>) -> Plot {
        self.subtitle = s.into();
        self
    }

    /// Axis labels.
    pub fn labels(mut self, x: impl Into<String>, y: impl Into<String>) -> Plot {
        self.x_label = x.into();
        self.y_label = y.into();
        self
    }

    /// Logarithmic x axis.
    pub fn log_x(mut self, on: bool) -> Plot {
        self.log_x = on;
        self
    }

    /// Logarithmic y axis.
    pub fn log_y(mut self, on: bool) -> Plot {
        self.log_y = on;
        self
    }

    /// The y axis includes zero (ignored on a log axis).
    pub fn y_zero(mut self, on: bool) -> Plot {
        self.y_zero = on;
        self
    }

    /// The x axis includes zero (ignored on a log axis).
    pub fn x_zero(mut self, on: bool) -> Plot {
        self.x_zero = on;
        self
    }

    /// Named ticks on x: the label of each position (experiment ids instead of run numbers).
    pub fn x_ticks(mut self, ticks: Vec<(f64, String)>) -> Plot {
        self.x_ticks = ticks;
        self
    }

    /// Adds a series.
    pub fn add(&mut self, s: Series) {
        self.series.push(s);
    }

    fn ok(&self, x: f64, y: f64) -> bool {
        x.is_finite() && y.is_finite() && (!self.log_x || x > 0.0) && (!self.log_y || y > 0.0)
    }

    /// Every decision of the plot: styles, markers, colours, ranges and ticks.
    pub fn spec(&self) -> PlotSpec {
        let styled: Vec<usize> = (0..self.series.len()).filter(|&i| !self.series[i].reference).collect();
        let staggered: Vec<usize> = styled.iter().copied().filter(|&i| self.series[i].line && !self.series[i].markers && !self.series[i].plain).collect();
        let series: Vec<SeriesSpec> = self
            .series
            .iter()
            .enumerate()
            .map(|(i, s)| {
                let k = styled.iter().position(|&j| j == i);
                let (col, line, marker) = match k {
                    Some(k) => (
                        s.colour_of.map_or_else(|| colour(k), |j| shade(colour(j), i)),
                        s.line.then(|| s.style.unwrap_or(LineStyle::CYCLE[k % LineStyle::CYCLE.len()])),
                        (!s.plain).then(|| s.marker.unwrap_or(Marker::CYCLE[k % Marker::CYCLE.len()])),
                    ),
                    None => (REFERENCE, s.line.then(|| s.style.unwrap_or(LineStyle::Dashed)), None),
                };
                let placement = match (marker, s.markers) {
                    (None, _) => MarkerPlacement::None,
                    (Some(_), true) => MarkerPlacement::Every,
                    (Some(_), false) => {
                        let j = staggered.iter().position(|&j| j == i).unwrap_or(0);
                        MarkerPlacement::Staggered { phase: (j as f64 + 0.5) / staggered.len().max(1) as f64, count: STAGGERED_MARKERS }
                    }
                };
                SeriesSpec { name: s.name.clone(), colour: col, line, marker, placement, points: s.points.clone(), error_bars: s.error_bars.clone() }
            })
            .collect();
        let (xr, yr) = self.ranges(&series);
        let legend = series.iter().filter(|s| !s.name.is_empty()).count() >= 2;
        let (w, h) = (self.width.max(200), self.height.max(150));
        PlotSpec {
            title: self.title.clone(),
            subtitle: self.subtitle.clone(),
            x: AxisSpec { label: self.x_label.clone(), log: self.log_x, range: xr, ticks: self.x_ticks.clone() },
            y: AxisSpec { label: self.y_label.clone(), log: self.log_y, range: yr, ticks: Vec::new() },
            series,
            legend,
            width: w,
            height: h,
        }
    }

    /// Axis ranges: x exactly the data unless markers sit on data points (then 3 % padding, so
    /// no marker is cut at an axis) or ticks are named (half a slot either side); y padded by
    /// 4 %; zero included where asked (an axis starting at zero is not padded below it).
    fn ranges(&self, series: &[SeriesSpec]) -> ((f64, f64), (f64, f64)) {
        let (mut xlo, mut xhi, mut ylo, mut yhi) = (f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY);
        let mut every = false;
        for s in series {
            for (k, &(x, y)) in s.points.iter().enumerate() {
                if self.ok(x, y) {
                    every |= s.placement == MarkerPlacement::Every;
                    let e = s.error_bars.get(k).copied().filter(|e| e.is_finite()).unwrap_or(0.0).abs();
                    xlo = xlo.min(x);
                    xhi = xhi.max(x);
                    for v in [y - e, y + e] {
                        if !self.log_y || v > 0.0 {
                            ylo = ylo.min(v);
                            yhi = yhi.max(v);
                        }
                    }
                }
            }
        }
        for &(x, _) in &self.x_ticks {
            xlo = xlo.min(x - 0.5);
            xhi = xhi.max(x + 0.5);
        }
        let zero = |lo: &mut f64, hi: &mut f64, on: bool, log: bool| {
            let from_zero = on && !log && lo.is_finite() && *lo >= 0.0;
            let to_zero = on && !log && hi.is_finite() && *hi <= 0.0;
            if from_zero {
                *lo = 0.0;
            }
            if to_zero {
                *hi = 0.0;
            }
            (from_zero, to_zero)
        };
        let zx = zero(&mut xlo, &mut xhi, self.x_zero, self.log_x);
        let zy = zero(&mut ylo, &mut yhi, self.y_zero, self.log_y);
        let xpad = if every && self.x_ticks.is_empty() { 0.03 } else { 0.0 };
        let clamp = |(a, b): (f64, f64), (z0, z1): (bool, bool)| (if z0 && a < 0.0 { 0.0 } else { a }, if z1 && b > 0.0 { 0.0 } else { b });
        let xr = clamp(range(xlo, xhi, self.log_x, xpad), if every { (false, false) } else { zx });
        let yr = clamp(range(ylo, yhi, self.log_y, 0.04), zy);
        (xr, yr)
    }

    /// Renders to an RGB buffer (row-major, 3 bytes per pixel).
    pub fn render(&self) -> Vec<u8> {
        render_spec(&self.spec())
    }

    /// Renders as an SVG document (text as text, in the "sans-serif" family; dashed lines as
    /// `stroke-dasharray`).
    pub fn render_svg(&self) -> String {
        render_spec_svg(&self.spec())
    }

    /// Writes the plot as an 8-bit RGB PNG at `path` and as SVG next to it (`path` with the
    /// extension `svg`).
    pub fn save_png(&self, path: &Path) -> Result<(), IoError> {
        let spec = self.spec();
        let data = render_spec(&spec);
        let (w, h) = (spec.width, spec.height);
        // encoded in memory, then written atomically (io::write_atomic_bytes): a full disk leaves
        // no truncated PNG under its final name (issue 26, class 10)
        let mut bytes = Vec::new();
        let mut enc = png::Encoder::new(&mut bytes, w, h);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        let mut wr = enc.write_header().map_err(|e| IoError::new(path, e))?;
        wr.write_image_data(&data).map_err(|e| IoError::new(path, e))?;
        wr.finish().map_err(|e| IoError::new(path, e))?;
        crate::io::write_atomic_bytes(path, &bytes)?;
        crate::io::write_atomic(&path.with_extension("svg"), &render_spec_svg(&spec))
    }

    /// Writes the plot as SVG (atomically).
    pub fn save_svg(&self, path: &Path) -> Result<(), IoError> {
        crate::io::write_atomic(path, &self.render_svg())
    }

    /// [`Self::save_png`] at the end of a run: a plot that cannot be written is a warning
    /// (`warning: plots not written: …`), the run keeps its exit code with its data complete
    /// (docs/outputs.md, "Data first, plots last"; every kind alike since issue 38).
    pub fn save_png_or_warn(&self, path: &Path) {
        if let Err(e) = self.save_png(path) {
            warn_not_written(&e);
        }
    }
}

/// The warning of a plot that could not be written ([`Plot::save_png_or_warn`]).
pub fn warn_not_written(e: &dyn std::fmt::Display) {
    tracing::warn!("plots not written: {e}");
}

mod render;
#[allow(unused_imports)]
use render::*;
pub use render::{dash, render_spec, render_spec_svg};

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn renders_series_in_their_colours_and_writes_png_and_svg() {
        let mut p = Plot::new("test").labels("x [m]", "y [1]").log_x(true).log_y(true);
        p.add(Series::new("a", (1..100).map(|i| (i as f64, (i * i) as f64)).collect()));
        p.add(Series::new("b", vec![(1.0, 0.0), (2.0, 4.0), (f64::NAN, 1.0), (50.0, 9.0)]).with_error_bars(vec![1.0, 1.0, 1.0, 2.0]));
        let px = p.render();
        assert_eq!(px.len(), 960 * 640 * 3);
        let has = |c: Rgb| px.chunks(3).any(|q| q == c);
        assert!(has(PALETTE[0]) && has(PALETTE[1]));
        // text was drawn: dark pixels outside the plot lines' colours
        assert!(px.chunks(3).filter(|q| q[0] < 60 && q[1] < 60 && q[2] < 60).count() > 500);
        let dir = std::env::temp_dir().join(format!("sinterdem-plot-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let f = dir.join("t.png");
        p.save_png(&f).unwrap();
        let bytes = std::fs::read(&f).unwrap();
        assert_eq!(&bytes[1..4], b"PNG");
        let svg = std::fs::read_to_string(dir.join("t.svg")).unwrap();
        assert!(svg.contains("<svg") && svg.contains("x [m]") && svg.contains("<text"));
        std::fs::remove_dir_all(&dir).ok();
    }

    /// The texts of an SVG, trimmed.
    fn texts(svg: &str) -> Vec<String> {
        svg.split("<text").skip(1).filter_map(|t| Some(t.split_once('>')?.1.split('<').next()?.trim().to_string())).collect()
    }

    #[test]
    fn tick_labels_and_ranges() {
        assert_eq!(tick_label(1e-3), "0.001");
        assert_eq!(tick_label(0.25), "0.25");
        assert_eq!(tick_label(2.5e-5), "2.5e-5");
        assert_eq!(tick_label(1200.0), "1200");
        assert_eq!(tick_label(3e6), "3e6");
        // the x axis ends where the data end
        assert_eq!(range(0.013, 0.41, false, 0.0), (0.013, 0.41));
        let (a, b) = range(6e-8, 5000.0, true, 0.0);
        assert!((a / 6e-8 - 1.0).abs() < 1e-9 && (b / 5000.0 - 1.0).abs() < 1e-9);
    }

    /// Issue 25: every series has its own colour, line style and marker shape, and the markers
    /// of lines sit at different places along each.
    #[test]
    fn series_get_distinct_styles_markers_and_staggered_markers() {
        let mut p = Plot::new("t");
        for name in ["x", "y", "z", "w"] {
            p.add(Series::new(name, vec![(0.0, 0.0), (1.0, 1.0)]));
        }
        let s = p.spec();
        let styles: Vec<_> = s.series.iter().map(|x| x.line).collect();
        assert_eq!(styles, LineStyle::CYCLE.map(Some).to_vec());
        let markers: Vec<_> = s.series.iter().map(|x| x.marker.unwrap()).collect();
        assert_eq!(markers, Marker::CYCLE[..4].to_vec());
        let mut colours: Vec<_> = s.series.iter().map(|x| x.colour).collect();
        colours.dedup();
        assert_eq!(colours.len(), 4);
        let phases: Vec<f64> = s
            .series
            .iter()
            .map(|x| match x.placement {
                MarkerPlacement::Staggered { phase, count } => {
                    assert_eq!(count, STAGGERED_MARKERS);
                    phase
                }
                other => panic!("{other:?}"),
            })
            .collect();
        assert_eq!(phases, vec![0.125, 0.375, 0.625, 0.875]);
        // 25 series: still every colour its own
        let mut p = Plot::new("t");
        for k in 0..25 {
            p.add(Series::new(format!("{k}"), vec![(0.0, k as f64)]));
        }
        let mut c: Vec<_> = p.spec().series.iter().map(|x| x.colour).collect();
        c.sort();
        c.dedup();
        assert_eq!(c.len(), 25);
        // a reference line takes no place in the cycles
        let mut p = Plot::new("t");
        p.add(Series::new("band", vec![(0.0, 1.0), (1.0, 1.0)]).reference());
        p.add(Series::new("data", vec![(0.0, 0.0), (1.0, 2.0)]));
        let s = p.spec();
        assert_eq!((s.series[0].colour, s.series[0].line, s.series[0].marker), (REFERENCE, Some(LineStyle::Dashed), None));
        assert_eq!((s.series[1].colour, s.series[1].line), (PALETTE[0], Some(LineStyle::Solid)));
    }

    /// Issue 25: x shrinkage was hidden under y (same data, drawn last): now both colours show.
    #[test]
    fn two_identical_curves_both_stay_visible() {
        let pts: Vec<(f64, f64)> = (0..200).map(|i| (i as f64, (i as f64 / 40.0).sqrt())).collect();
        let mut p = Plot::new("");
        p.add(Series::new("", pts.clone()));
        p.add(Series::new("", pts));
        let px = p.render();
        let count = |c: Rgb| px.chunks(3).filter(|q| *q == c).count();
        let (first, second) = (count(colour(0)), count(colour(1)));
        // the first curve's markers and the gaps of the second's dashes show it
        assert!(first > 300 && second > 300, "{first} {second}");
    }

    /// Issue 25: layer_profile.png stretched 0.0191–0.0198 to the full axis; an axis that asks for
    /// zero starts at zero (and is not padded below it); markers at every point pad x.
    #[test]
    fn honest_axes_include_zero_and_never_cut_markers() {
        let mut p = Plot::new("t").y_zero(true);
        p.add(Series::new("layers", vec![(10e-6, 0.0191), (50e-6, 0.0198), (90e-6, 0.0194)]).with_markers());
        let s = p.spec();
        assert_eq!(s.y.range.0, 0.0);
        assert!(s.y.range.1 > 0.0198 && s.y.range.1 < 0.0198 * 1.05);
        assert!(s.x.range.0 < 10e-6 && s.x.range.1 > 90e-6, "{:?}", s.x.range);
        // without zero: the data range (padded) as before
        let mut p = Plot::new("t");
        p.add(Series::new("layers", vec![(0.0, 0.0191), (1.0, 0.0198)]));
        let s = p.spec();
        assert!(s.y.range.0 > 0.019 && s.x.range == (0.0, 1.0));
        // negative data and zero: the axis ends at zero
        let mut p = Plot::new("t").y_zero(true);
        p.add(Series::new("f", vec![(0.0, -3.0), (1.0, -1.0)]));
        assert_eq!(p.spec().y.range.1, 0.0);
        // a log axis ignores zero
        let mut p = Plot::new("t").y_zero(true).log_y(true);
        p.add(Series::new("f", vec![(1.0, 1e-3), (2.0, 1e-1)]));
        assert!(p.spec().y.range.0 > 0.0);
    }

    /// Named ticks: the experiment ids, the axis half a slot wider than the first and last.
    #[test]
    fn named_ticks_label_the_runs() {
        let ticks: Vec<(f64, String)> = (1..=28).map(|k| (k as f64, format!("E{k}B"))).collect();
        let mut p = Plot::new("titanium").x_ticks(ticks.clone());
        p.add(Series::new("runs", (1..=28).map(|k| (k as f64, 0.01 * k as f64)).collect()).points_only());
        let s = p.spec();
        assert_eq!(s.x.range, (0.5, 28.5));
        assert_eq!(s.x.ticks, ticks);
        let t = texts(&p.render_svg());
        for id in ["E1B", "E14B", "E28B"] {
            assert!(t.contains(&id.to_string()), "{id} missing: {t:?}");
        }
        // 28 ids of 4 characters do not fit one row in 960 px: staggered rows
        assert!(tick_rows(&ticks, 30.0, 9.0) >= 2);
        assert_eq!(tick_rows(&ticks[..5], 150.0, 9.0), 1);
    }

    #[test]
    fn a_long_subtitle_is_split_in_two_lines() {
        let long = "28 two-particle runs, heating counted from 793 K, each experiment's own particle diameter; one line per peak temperature and heating rate";
        assert_eq!(
            subtitle_lines(long, 960.0, 17.0),
            ["28 two-particle runs, heating counted from 793 K, each experiment's own particle diameter;", "one line per peak temperature and heating rate"]
        );
        assert_eq!(subtitle_lines("805 particles of copper", 960.0, 17.0), ["805 particles of copper"]);
        assert!(subtitle_lines("", 960.0, 17.0).is_empty());
    }

    #[test]
    fn units_follow_the_span() {
        assert_eq!(time_unit(5000.0, false).name, "min");
        assert_eq!(time_unit(100.0, false).name, "s");
        assert_eq!(time_unit(20.0 * 3600.0, false).name, "h");
        assert_eq!(time_unit(0.5, false).name, "ms");
        assert_eq!(time_unit(2e-4, false).name, "µs");
        assert_eq!(time_unit(5000.0, true).name, "s");
        assert_eq!(length_unit(1.5e-4).name, "µm");
        assert!((length_unit(1.5e-4).of(1.5e-4) - 150.0).abs() < 1e-9);
        assert_eq!(length_unit(2e-3).name, "mm");
        assert_eq!(length_unit(5e-8).name, "nm");
        assert_eq!(fmt_time(5000.0), "83.3 min");
        assert_eq!(fmt_length(25e-6), "25 µm");
    }

    #[test]
    fn dashes_cut_a_line_into_pattern_pieces() {
        let line = [(0.0, 0.0), (60.0, 0.0), (60.0, 40.0)];
        let pieces = dash(&line, &[10.0, 5.0]);
        // 100 px of 15 px periods: 7 dashes, each 10 px long, the one round the corner included
        assert_eq!(pieces.len(), 7);
        for p in &pieces {
            let l: f64 = p.windows(2).map(|w| (w[1].0 - w[0].0).hypot(w[1].1 - w[0].1)).sum();
            assert!((l - 10.0).abs() < 1e-9, "{p:?}");
        }
        assert_eq!(pieces[4], vec![(60.0, 0.0), (60.0, 10.0)]);
        assert_eq!(dash(&line, &[]), vec![line.to_vec()]);
        // markers along: the middle of the path
        let m = along(&[line.to_vec()], &[0.5, 1.0]);
        assert_eq!(m, vec![(50.0, 0.0), (60.0, 40.0)]);
    }

    /// The SVG draws each series' line with its own dash array, and title and subtitle as text.
    #[test]
    fn svg_has_one_dash_array_per_style_and_the_subtitle() {
        let mut p = Plot::new("copper compact: shrinkage").subtitle("805 particles of copper, mean radius 25 µm");
        for name in ["x", "y", "z", "w"] {
            p.add(Series::new(name, (0..50).map(|i| (i as f64, i as f64 * 0.01)).collect()));
        }
        let svg = p.render_svg();
        let t = texts(&svg);
        assert!(t.contains(&"copper compact: shrinkage".to_string()) && t.contains(&"805 particles of copper, mean radius 25 µm".to_string()), "{t:?}");
        let arrays: Vec<&str> = svg.match_indices("stroke-dasharray=\"").map(|(i, _)| svg[i + 18..].split('"').next().unwrap()).collect();
        let mut distinct = arrays.clone();
        distinct.sort();
        distinct.dedup();
        assert_eq!(distinct, vec!["0.5,7", "10,9", "12,8,0.5,8"], "{arrays:?}");
        // each dashed series: its line and its legend sample
        assert_eq!(arrays.len(), 6);
    }
}
