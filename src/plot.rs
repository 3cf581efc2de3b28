//! The shared line-plot facility: several named series, linear or logarithmic axes, axis labels,
//! title, legend, markers and error bars, drawn with the `plotters` crate. Every plot is written as
//! PNG and SVG ([`Plot::save_png`] writes both). Labels use DejaVu Sans, embedded in the binary
//! (`assets/fonts/DejaVuSans.ttf`, licence in `assets/fonts/LICENSE-DejaVu.txt`), so no system
//! fonts are needed.
//!
//! ```no_run
//! use sinterdem::plot::{Plot, Series};
//! let mut p = Plot::new("Neck growth").labels("time t [s]", "y1/R [1]").log_x(true);
//! p.add(Series::new("copper", vec![(1.0, 0.1), (10.0, 0.14), (100.0, 0.21)]));
//! p.save_png(std::path::Path::new("neck.png")).unwrap(); // neck.png and neck.svg
//! ```

use crate::error::IoError;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;

/// One named curve.
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    pub name: String,
    /// (x, y) points in drawing order; non-finite points (and non-positive ones on a log axis) are
    /// skipped and break the line.
    pub points: Vec<(f64, f64)>,
    /// Draw a marker at every point.
    pub markers: bool,
    /// Connect the points with a line.
    pub line: bool,
    /// Half-widths of vertical error bars, one per point (empty: none).
    pub error_bars: Vec<f64>,
}

impl Series {
    /// A line without markers.
    pub fn new(name: impl Into<String>, points: Vec<(f64, f64)>) -> Series {
        Series { name: name.into(), points, markers: false, line: true, error_bars: Vec::new() }
    }

    /// Also draw markers.
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
}

/// A line plot.
#[derive(Debug, Clone, PartialEq)]
pub struct Plot {
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    pub log_x: bool,
    pub log_y: bool,
    /// Image size in pixels.
    pub width: u32,
    pub height: u32,
    pub series: Vec<Series>,
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

/// The embedded font, registered once as plotters' "sans-serif".
fn font() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        let bytes: &'static [u8] = include_bytes!("../assets/fonts/DejaVuSans.ttf");
        let _ = plotters::style::register_font("sans-serif", FontStyle::Normal, bytes);
    });
}

/// A tick label: at most 4 significant digits, plain for 1e-3 ≤ |v| < 1e5, else `2.5e-5`.
pub fn tick_label(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return if v == 0.0 { "0".into() } else { format!("{v}") };
    }
    let trim = |s: String| if s.contains('.') { s.trim_end_matches('0').trim_end_matches('.').to_string() } else { s };
    let a = v.abs();
    if (1e-3..1e5).contains(&a) {
        let decimals = (3 - a.log10().floor() as i32).max(0) as usize;
        trim(format!("{v:.decimals$}"))
    } else {
        let e = a.log10().floor() as i32;
        let m = v / 10f64.powi(e);
        let (m, e) = if (m.abs() * 1000.0).round() >= 10000.0 { (m / 10.0, e + 1) } else { (m, e) };
        format!("{}e{e}", trim(format!("{m:.3}")))
    }
}

/// Plot-area range of the points: x exactly the data, y padded by 4 % (a decade fraction on a log axis).
fn range(lo: f64, hi: f64, log: bool, pad: f64) -> (f64, f64) {
    if !(lo.is_finite() && hi.is_finite()) {
        return if log { (1.0, 10.0) } else { (0.0, 1.0) };
    }
    if log {
        let (a, b) = (lo.log10(), hi.log10());
        let (a, b) = if b - a < 1e-9 { (a - 0.5, b + 0.5) } else { (a, b) };
        let p = pad * (b - a);
        (10f64.powf(a - p), 10f64.powf(b + p))
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
        Plot { title: title.into(), x_label: String::new(), y_label: String::new(), log_x: false, log_y: false, width: 960, height: 640, series: Vec::new() }
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

    /// Adds a series.
    pub fn add(&mut self, s: Series) {
        self.series.push(s);
    }

    fn ok(&self, x: f64, y: f64) -> bool {
        x.is_finite() && y.is_finite() && (!self.log_x || x > 0.0) && (!self.log_y || y > 0.0)
    }

    /// Data ranges (x exact, y padded; error bars included).
    fn ranges(&self) -> ((f64, f64), (f64, f64)) {
        let (mut xlo, mut xhi, mut ylo, mut yhi) = (f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY);
        for s in &self.series {
            for (k, &(x, y)) in s.points.iter().enumerate() {
                if self.ok(x, y) {
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
        (range(xlo, xhi, self.log_x, 0.0), range(ylo, yhi, self.log_y, 0.04))
    }

    fn size(&self) -> (u32, u32) {
        (self.width.max(200), self.height.max(150))
    }

    /// Draws onto any plotters backend.
    fn draw<DB: DrawingBackend>(&self, root: DrawingArea<DB, Shift>, raster: bool) -> DrawResult<DB::ErrorType> {
        font();
        root.fill(&WHITE)?;
        let ((x0, x1), (y0, y1)) = self.ranges();
        match (self.log_x, self.log_y) {
            (false, false) => self.chart(&root, x0..x1, y0..y1, raster),
            (true, false) => self.chart(&root, (x0..x1).log_scale(), y0..y1, raster),
            (false, true) => self.chart(&root, x0..x1, (y0..y1).log_scale(), raster),
            (true, true) => self.chart(&root, (x0..x1).log_scale(), (y0..y1).log_scale(), raster),
        }?;
        root.present()
    }

    fn chart<DB, X, Y>(&self, root: &DrawingArea<DB, Shift>, xr: X, yr: Y, raster: bool) -> DrawResult<DB::ErrorType>
    where
        DB: DrawingBackend,
        X: plotters::coord::ranged1d::AsRangedCoord<Value = f64>,
        Y: plotters::coord::ranged1d::AsRangedCoord<Value = f64>,
        X::CoordDescType: plotters::coord::ranged1d::ValueFormatter<f64>,
        Y::CoordDescType: plotters::coord::ranged1d::ValueFormatter<f64>,
    {
        let (w, h) = self.size();
        let scale = (h as f64 / 640.0).clamp(0.5, 3.0);
        let px = |v: f64| (v * scale).round() as u32;
        let tick_font = ("sans-serif", px(17.0) as f64);
        let label_font = ("sans-serif", px(20.0) as f64);
        // room for the widest y tick label (≈ 0.6 em per character) plus the rotated axis title
        let ((_, _), (ylo, yhi)) = self.ranges();
        let widest = [ylo, yhi, 0.5 * (ylo + yhi), -ylo.abs().max(yhi.abs())].iter().map(|&v| tick_label(v).chars().count()).max().unwrap_or(4).max(4);
        let y_area = px(17.0 * 0.62 * widest as f64 + 44.0);
        let mut chart = ChartBuilder::on(root)
            .caption(&self.title, ("sans-serif", px(24.0) as f64))
            .margin_top(px(10.0))
            .margin_left(px(10.0))
            .margin_right(px(28.0))
            .margin_bottom(px(10.0))
            .x_label_area_size(px(62.0))
            .y_label_area_size(y_area)
            .build_cartesian_2d(xr, yr)?;
        let fmt = |v: &f64| tick_label(*v);
        chart
            .configure_mesh()
            .x_desc(self.x_label.as_str())
            .y_desc(self.y_label.as_str())
            .axis_desc_style(label_font)
            .label_style(tick_font)
            .x_label_formatter(&fmt)
            .y_label_formatter(&fmt)
            .x_labels(if w >= 700 { 9 } else { 5 })
            .y_labels(8)
            .light_line_style(RGBColor(240, 240, 240))
            .bold_line_style(RGBColor(215, 215, 215))
            .draw()?;
        let lw = px(2.5).max(1);
        let named = self.series.iter().filter(|s| !s.name.is_empty()).count();
        for (k, s) in self.series.iter().enumerate() {
            let c = PALETTE[k % PALETTE.len()];
            let col = RGBColor(c[0], c[1], c[2]);
            let style = ShapeStyle::from(&col).stroke_width(lw);
            // runs of drawable points: a skipped point breaks the line
            let mut runs: Vec<Vec<(f64, f64)>> = vec![Vec::new()];
            for &(x, y) in &s.points {
                if self.ok(x, y) {
                    runs.last_mut().expect("one run").push((x, y));
                } else if !runs.last().expect("one run").is_empty() {
                    runs.push(Vec::new());
                }
            }
            let mut first = true;
            if s.line {
                for run in runs.iter().filter(|r| !r.is_empty()) {
                    let run = self.thin(run, w, h);
                    let a = if raster {
                        // plotters' bitmap polygonisation of a wide polyline breaks at sharp turns
                        // (histogram steps): segments with round joints instead
                        let r = (lw / 2).max(1);
                        let joints: Vec<(f64, f64)> = if lw > 1 { run.clone() } else { Vec::new() };
                        chart.draw_series(joints.into_iter().map(|p| Circle::new(p, r, col.filled())))?;
                        chart.draw_series(run.windows(2).map(|q| PathElement::new(vec![q[0], q[1]], style)))?
                    } else {
                        chart.draw_series(LineSeries::new(run.iter().copied(), style))?
                    };
                    if first && !s.name.is_empty() && named >= 2 {
                        let mk = s.markers;
                        a.label(s.name.as_str()).legend(move |(x, y)| {
                            let l = PathElement::new(vec![(x, y), (x + 24, y)], style);
                            let m = Circle::new((x + 12, y), if mk { 4 } else { 0 }, col.filled());
                            EmptyElement::at((0, 0)) + l + m
                        });
                        first = false;
                    }
                }
            }
            if s.markers {
                let r = px(4.0).max(2);
                let a = chart.draw_series(runs.iter().flatten().map(|&(x, y)| Circle::new((x, y), r, col.filled())))?;
                if first && !s.name.is_empty() && named >= 2 {
                    a.label(s.name.as_str()).legend(move |(x, y)| Circle::new((x + 12, y), 4, col.filled()));
                }
            }
            if !s.error_bars.is_empty() {
                let bars: Vec<(f64, f64, f64, f64)> = s
                    .points
                    .iter()
                    .zip(&s.error_bars)
                    .filter(|&(&(x, y), e)| self.ok(x, y) && e.is_finite())
                    .map(|(&(x, y), &e)| {
                        let lo = if self.log_y && y - e.abs() <= 0.0 { y } else { y - e.abs() };
                        (x, lo, y, y + e.abs())
                    })
                    .collect();
                chart.draw_series(bars.into_iter().map(|(x, lo, y, hi)| ErrorBar::new_vertical(x, lo, y, hi, style, px(10.0))))?;
            }
        }
        if named >= 2 {
            chart
                .configure_series_labels()
                .position(self.legend_corner())
                .margin(px(12.0))
                .label_font(("sans-serif", px(16.0) as f64))
                .background_style(RGBColor(252, 252, 252).mix(0.9))
                .border_style(RGBColor(160, 160, 160))
                .draw()?;
        }
        Ok(())
    }

    /// Drops points closer than about half a pixel to the last kept one (a plot of 10⁵ rows draws
    /// as fast and small as one of 10³).
    fn thin(&self, run: &[(f64, f64)], w: u32, h: u32) -> Vec<(f64, f64)> {
        let ((x0, x1), (y0, y1)) = self.ranges();
        let f = |v: f64, a: f64, b: f64, log: bool| if log { (v.ln() - a.ln()) / (b.ln() - a.ln()) } else { (v - a) / (b - a) };
        let (sx, sy) = (w as f64, h as f64);
        let mut out: Vec<(f64, f64)> = Vec::with_capacity(run.len());
        let mut last = (f64::NAN, f64::NAN);
        for (k, &(x, y)) in run.iter().enumerate() {
            let p = (f(x, x0, x1, self.log_x) * sx, f(y, y0, y1, self.log_y) * sy);
            if k == 0 || k + 1 == run.len() || (p.0 - last.0).hypot(p.1 - last.1) >= 0.5 {
                out.push((x, y));
                last = p;
            }
        }
        out
    }

    /// The corner of the plot area that hides the fewest points.
    fn legend_corner(&self) -> SeriesLabelPosition {
        let ((x0, x1), (y0, y1)) = self.ranges();
        let f = |v: f64, a: f64, b: f64, log: bool| if log { (v.ln() - a.ln()) / (b.ln() - a.ln()) } else { (v - a) / (b - a) };
        let named = self.series.iter().filter(|s| !s.name.is_empty()).count() as f64;
        let (lw, lh) = (0.35, (0.06 * named + 0.04).min(0.6));
        let corners = [
            (SeriesLabelPosition::UpperRight, 1.0 - lw, 1.0 - lh),
            (SeriesLabelPosition::UpperLeft, 0.0, 1.0 - lh),
            (SeriesLabelPosition::LowerRight, 1.0 - lw, 0.0),
            (SeriesLabelPosition::LowerLeft, 0.0, 0.0),
        ];
        let pts: Vec<(f64, f64)> = self
            .series
            .iter()
            .flat_map(|s| s.points.iter())
            .filter(|&&(x, y)| self.ok(x, y))
            .map(|&(x, y)| (f(x, x0, x1, self.log_x), f(y, y0, y1, self.log_y)))
            .collect();
        let mut best = (usize::MAX, SeriesLabelPosition::UpperRight);
        for (pos, cx, cy) in corners {
            let hidden = pts.iter().filter(|&&(u, v)| u >= cx - 0.02 && u <= cx + lw + 0.02 && v >= cy - 0.02 && v <= cy + lh + 0.02).count();
            if hidden < best.0 {
                best = (hidden, pos);
            }
        }
        best.1
    }

    /// Renders to an RGB buffer (row-major, 3 bytes per pixel).
    pub fn render(&self) -> Vec<u8> {
        let (w, h) = self.size();
        let mut buf = vec![255u8; (w * h * 3) as usize];
        {
            let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
            // drawing into memory cannot fail for I/O reasons; a failure leaves a partial image
            let _ = self.draw(root, true);
        }
        buf
    }

    /// Renders as an SVG document (text as text, in the "sans-serif" family).
    pub fn render_svg(&self) -> String {
        let mut s = String::new();
        {
            let root = SVGBackend::with_string(&mut s, self.size()).into_drawing_area();
            let _ = self.draw(root, false);
        }
        s
    }

    /// Writes the plot as an 8-bit RGB PNG at `path` and as SVG next to it (`path` with the
    /// extension `svg`).
    pub fn save_png(&self, path: &Path) -> Result<(), IoError> {
        let data = self.render();
        let (w, h) = self.size();
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
        self.save_svg(&path.with_extension("svg"))
    }

    /// Writes the plot as SVG (atomically).
    pub fn save_svg(&self, path: &Path) -> Result<(), IoError> {
        crate::io::write_atomic(path, &self.render_svg())
    }
}

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
}
