//! A small shared PNG line-plot facility: several named series, linear or logarithmic axes, axis
//! labels, title and legend. Pure Rust (the `png` encoder and the public-domain `font8x8` bitmap
//! font), so it works on a fresh machine with no system fonts.
//!
//! ```no_run
//! use sinterdem::plot::{Plot, Series};
//! let mut p = Plot::new("Neck growth").labels("time t [s]", "y1/R [1]").log_x(true);
//! p.add(Series::new("copper", vec![(1.0, 0.1), (10.0, 0.14), (100.0, 0.21)]));
//! p.save_png(std::path::Path::new("neck.png")).unwrap();
//! ```

use crate::error::IoError;
use font8x8::{UnicodeFonts, BASIC_FONTS};
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
    /// Symmetric y error bars (one standard deviation, same unit as y) per point; empty: none.
    pub y_errors: Vec<f64>,
}

impl Series {
    /// A line without markers.
    pub fn new(name: impl Into<String>, points: Vec<(f64, f64)>) -> Series {
        Series { name: name.into(), points, markers: false, line: true, y_errors: Vec::new() }
    }

    /// Markers only, no connecting line.
    pub fn markers_only(mut self) -> Series {
        self.markers = true;
        self.line = false;
        self
    }

    /// Draw error bars y ± e (one per point).
    pub fn with_y_errors(mut self, e: Vec<f64>) -> Series {
        self.y_errors = e;
        self
    }

    /// Also draw markers.
    pub fn with_markers(mut self) -> Series {
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

/// An RGB raster.
struct Canvas {
    w: i64,
    h: i64,
    px: Vec<u8>,
}

impl Canvas {
    fn new(w: u32, h: u32) -> Canvas {
        Canvas { w: w as i64, h: h as i64, px: vec![255; (w * h * 3) as usize] }
    }

    #[inline]
    fn blend(&mut self, x: i64, y: i64, c: Rgb, alpha: f64) {
        if x < 0 || y < 0 || x >= self.w || y >= self.h || alpha <= 0.0 {
            return;
        }
        let a = alpha.min(1.0);
        let i = ((y * self.w + x) * 3) as usize;
        for k in 0..3 {
            let old = self.px[i + k] as f64;
            self.px[i + k] = (old + (c[k] as f64 - old) * a).round() as u8;
        }
    }

    fn rect(&mut self, x0: i64, y0: i64, x1: i64, y1: i64, c: Rgb) {
        for y in y0..=y1 {
            for x in x0..=x1 {
                self.blend(x, y, c, 1.0);
            }
        }
    }

    /// Anti-aliased segment of width `wd` pixels (coverage from the distance to the segment).
    fn line(&mut self, x0: f64, y0: f64, x1: f64, y1: f64, wd: f64, c: Rgb) {
        let r = wd / 2.0 + 1.0;
        let (minx, maxx) = ((x0.min(x1) - r).floor() as i64, (x0.max(x1) + r).ceil() as i64);
        let (miny, maxy) = ((y0.min(y1) - r).floor() as i64, (y0.max(y1) + r).ceil() as i64);
        let (minx, maxx) = (minx.max(0), maxx.min(self.w - 1));
        let (miny, maxy) = (miny.max(0), maxy.min(self.h - 1));
        let (dx, dy) = (x1 - x0, y1 - y0);
        let l2 = dx * dx + dy * dy;
        for y in miny..=maxy {
            for x in minx..=maxx {
                let (px, py) = (x as f64, y as f64);
                let t = if l2 > 0.0 { (((px - x0) * dx + (py - y0) * dy) / l2).clamp(0.0, 1.0) } else { 0.0 };
                let (qx, qy) = (x0 + t * dx - px, y0 + t * dy - py);
                let d = (qx * qx + qy * qy).sqrt();
                let cov = (wd / 2.0 + 0.5 - d).clamp(0.0, 1.0);
                self.blend(x, y, c, cov);
            }
        }
    }

    fn text(&mut self, x: i64, y: i64, s: &str, scale: i64, c: Rgb) {
        let mut cx = x;
        for ch in s.chars() {
            let g = BASIC_FONTS.get(ch).or_else(|| BASIC_FONTS.get('?')).unwrap_or([0; 8]);
            for (row, bits) in g.iter().enumerate() {
                for col in 0..8 {
                    if bits >> col & 1 == 1 {
                        for sy in 0..scale {
                            for sx in 0..scale {
                                self.blend(cx + col * scale + sx, y + row as i64 * scale + sy, c, 1.0);
                            }
                        }
                    }
                }
            }
            cx += 8 * scale;
        }
    }

    /// Text rotated by 90° counter-clockwise, its baseline running upwards from (x, y).
    fn text_vertical(&mut self, x: i64, y: i64, s: &str, scale: i64, c: Rgb) {
        let mut cy = y;
        for ch in s.chars() {
            let g = BASIC_FONTS.get(ch).or_else(|| BASIC_FONTS.get('?')).unwrap_or([0; 8]);
            for (row, bits) in g.iter().enumerate() {
                for col in 0..8 {
                    if bits >> col & 1 == 1 {
                        for sy in 0..scale {
                            for sx in 0..scale {
                                self.blend(x + row as i64 * scale + sx, cy - col * scale - sy, c, 1.0);
                            }
                        }
                    }
                }
            }
            cy -= 8 * scale;
        }
    }
}

fn text_width(s: &str, scale: i64) -> i64 {
    s.chars().count() as i64 * 8 * scale
}

/// Axis mapping.
#[derive(Clone, Copy)]
struct Axis {
    lo: f64,
    hi: f64,
    log: bool,
}

impl Axis {
    fn tr(&self, v: f64) -> f64 {
        if self.log { v.log10() } else { v }
    }
    /// Fraction 0..1 along the axis.
    fn frac(&self, v: f64) -> f64 {
        (self.tr(v) - self.tr(self.lo)) / (self.tr(self.hi) - self.tr(self.lo))
    }
    fn ok(&self, v: f64) -> bool {
        v.is_finite() && (!self.log || v > 0.0)
    }

    /// Range and ticks from data bounds.
    fn fit(mut lo: f64, mut hi: f64, log: bool) -> (Axis, Vec<f64>) {
        if !lo.is_finite() || !hi.is_finite() {
            lo = if log { 0.1 } else { 0.0 };
            hi = 1.0;
        }
        if log {
            let (mut a, mut b) = (lo.log10().floor(), hi.log10().ceil());
            if b <= a {
                a -= 1.0;
                b += 1.0;
            }
            let span = (b - a) as i64;
            let every = ((span + 9) / 10).max(1);
            let ticks = (0..=span).filter(|k| k % every == 0).map(|k| 10f64.powi((a as i64 + k) as i32)).collect();
            (Axis { lo: 10f64.powf(a), hi: 10f64.powf(b), log }, ticks)
        } else {
            if hi <= lo {
                let d = if lo == 0.0 { 1.0 } else { lo.abs() * 0.1 };
                lo -= d;
                hi += d;
            }
            let raw = (hi - lo) / 6.0;
            let mag = 10f64.powf(raw.log10().floor());
            let step = [1.0, 2.0, 2.5, 5.0, 10.0].iter().map(|m| m * mag).find(|s| *s >= raw).unwrap_or(10.0 * mag);
            let a = (lo / step).floor() * step;
            let b = (hi / step).ceil() * step;
            let n = ((b - a) / step).round() as i64;
            let ticks = (0..=n).map(|k| a + k as f64 * step).collect();
            (Axis { lo: a, hi: b, log }, ticks)
        }
    }
}

fn tick_label(v: f64, log: bool, step: f64) -> String {
    if log {
        let e = v.log10().round() as i32;
        return match e {
            0 => "1".into(),
            1 => "10".into(),
            -1 => "0.1".into(),
            _ => format!("1e{e}"),
        };
    }
    if v == 0.0 {
        return "0".into();
    }
    let a = v.abs();
    if !(1e-3..1e5).contains(&a) {
        let s = format!("{v:.1e}");
        return s.replace(".0e", "e");
    }
    let decimals = if step >= 1.0 { 0 } else { (-step.log10().floor()) as usize + 1 };
    let s = format!("{v:.decimals$}");
    if s.contains('.') { s.trim_end_matches('0').trim_end_matches('.').to_string() } else { s }
}

impl Plot {
    /// An empty 960×640 plot with linear axes.
    pub fn new(title: impl Into<String>) -> Plot {
        Plot {
            title: title.into(),
            x_label: String::new(),
            y_label: String::new(),
            log_x: false,
            log_y: false,
            width: 960,
            height: 640,
            series: Vec::new(),
        }
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

    /// Renders to an RGB buffer (row-major, 3 bytes per pixel).
    pub fn render(&self) -> Vec<u8> {
        let mut cv = Canvas::new(self.width.max(200), self.height.max(150));
        let (w, h) = (cv.w, cv.h);
        let (mut xlo, mut xhi, mut ylo, mut yhi) = (f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY);
        let okx = |v: f64| v.is_finite() && (!self.log_x || v > 0.0);
        let oky = |v: f64| v.is_finite() && (!self.log_y || v > 0.0);
        for s in &self.series {
            for (k, &(x, y)) in s.points.iter().enumerate() {
                if okx(x) && oky(y) {
                    xlo = xlo.min(x);
                    xhi = xhi.max(x);
                    ylo = ylo.min(y);
                    yhi = yhi.max(y);
                    let e = s.y_errors.get(k).copied().unwrap_or(0.0);
                    if e > 0.0 && e.is_finite() {
                        if oky(y - e) {
                            ylo = ylo.min(y - e);
                        }
                        yhi = yhi.max(y + e);
                    }
                }
            }
        }
        let (ax, xt) = Axis::fit(xlo, xhi, self.log_x);
        let (ay, yt) = Axis::fit(ylo, yhi, self.log_y);
        let (left, right, top, bottom) = (136i64, w - 30, 50i64, h - 80);
        let black = [0, 0, 0];
        let grid = [225, 225, 225];
        let px = |x: f64| left as f64 + ax.frac(x) * (right - left) as f64;
        let py = |y: f64| bottom as f64 - ay.frac(y) * (bottom - top) as f64;
        // grid and ticks
        let xstep = if xt.len() > 1 { xt[1] - xt[0] } else { 1.0 };
        let ystep = if yt.len() > 1 { yt[1] - yt[0] } else { 1.0 };
        for &t in &xt {
            let x = px(t).round() as i64;
            cv.rect(x, top, x, bottom, grid);
            cv.rect(x, bottom, x, bottom + 6, black);
            let lab = tick_label(t, self.log_x, xstep);
            cv.text(x - text_width(&lab, 2) / 2, bottom + 12, &lab, 2, black);
        }
        for &t in &yt {
            let y = py(t).round() as i64;
            cv.rect(left, y, right, y, grid);
            cv.rect(left - 6, y, left, y, black);
            let lab = tick_label(t, self.log_y, ystep);
            cv.text(left - 10 - text_width(&lab, 2), y - 8, &lab, 2, black);
        }
        // frame
        cv.rect(left, top, right, top, black);
        cv.rect(left, bottom, right, bottom, black);
        cv.rect(left, top, left, bottom, black);
        cv.rect(right, top, right, bottom, black);
        // series
        for (k, s) in self.series.iter().enumerate() {
            let col = PALETTE[k % PALETTE.len()];
            let mut last: Option<(f64, f64)> = None;
            for (i, &(x, y)) in s.points.iter().enumerate() {
                let e = s.y_errors.get(i).copied().unwrap_or(0.0);
                if e > 0.0 && e.is_finite() && ax.ok(x) && ay.ok(y) {
                    let lo = if ay.ok(y - e) { py(y - e) } else { bottom as f64 };
                    let (xx, hi) = (px(x), py(y + e).max(top as f64));
                    cv.line(xx, lo, xx, hi, 1.5, col);
                    cv.line(xx - 5.0, lo, xx + 5.0, lo, 1.5, col);
                    cv.line(xx - 5.0, hi, xx + 5.0, hi, 1.5, col);
                }
                if !(ax.ok(x) && ay.ok(y)) {
                    last = None;
                    continue;
                }
                let p = (px(x), py(y));
                if s.line
                    && let Some(q) = last {
                    cv.line(q.0, q.1, p.0, p.1, 2.5, col);
                }
                if s.markers {
                    cv.line(p.0 - 0.01, p.1, p.0 + 0.01, p.1, 7.0, col);
                }
                last = Some(p);
            }
        }
        // title and labels
        cv.text(w / 2 - text_width(&self.title, 2) / 2, 14, &self.title, 2, black);
        cv.text((left + right) / 2 - text_width(&self.x_label, 2) / 2, h - 36, &self.x_label, 2, black);
        cv.text_vertical(8, (top + bottom) / 2 + text_width(&self.y_label, 2) / 2, &self.y_label, 2, black);
        // legend
        let named: Vec<(usize, &Series)> = self.series.iter().enumerate().filter(|(_, s)| !s.name.is_empty()).collect();
        if !named.is_empty() {
            let lw = named.iter().map(|(_, s)| text_width(&s.name, 2)).max().unwrap_or(0) + 60;
            let lh = named.len() as i64 * 22 + 10;
            // the corner of the plot area that hides the fewest points
            let corners = [(left + 12, top + 12), (right - 12 - lw, top + 12), (left + 12, bottom - 12 - lh), (right - 12 - lw, bottom - 12 - lh)];
            let hidden = |(cx, cy): (i64, i64)| {
                self.series
                    .iter()
                    .flat_map(|s| s.points.iter())
                    .filter(|&&(x, y)| ax.ok(x) && ay.ok(y))
                    .filter(|&&(x, y)| {
                        let (qx, qy) = (px(x), py(y));
                        qx >= (cx - 6) as f64 && qx <= (cx + lw + 6) as f64 && qy >= (cy - 6) as f64 && qy <= (cy + lh + 6) as f64
                    })
                    .count()
            };
            let (lx, ly) = corners.iter().copied().min_by_key(|&c| hidden(c)).unwrap_or(corners[0]);
            cv.rect(lx, ly, lx + lw, ly + lh, [250, 250, 250]);
            cv.rect(lx, ly, lx + lw, ly, [160, 160, 160]);
            cv.rect(lx, ly + lh, lx + lw, ly + lh, [160, 160, 160]);
            cv.rect(lx, ly, lx, ly + lh, [160, 160, 160]);
            cv.rect(lx + lw, ly, lx + lw, ly + lh, [160, 160, 160]);
            for (i, (k, s)) in named.iter().enumerate() {
                let col = PALETTE[k % PALETTE.len()];
                let yy = ly + 8 + i as i64 * 22;
                cv.line((lx + 8) as f64, (yy + 8) as f64, (lx + 40) as f64, (yy + 8) as f64, 2.5, col);
                if s.markers {
                    cv.line((lx + 24) as f64, (yy + 8) as f64, (lx + 24) as f64 + 0.01, (yy + 8) as f64, 7.0, col);
                }
                cv.text(lx + 48, yy, &s.name, 2, black);
            }
        }
        cv.px
    }

    /// Writes the plot as an 8-bit RGB PNG.
    pub fn save_png(&self, path: &Path) -> Result<(), IoError> {
        let data = self.render();
        let file = std::fs::File::create(path).map_err(|e| IoError::new(path, e))?;
        let mut enc = png::Encoder::new(std::io::BufWriter::new(file), self.width.max(200), self.height.max(150));
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        let mut wr = enc.write_header().map_err(|e| IoError::new(path, e))?;
        wr.write_image_data(&data).map_err(|e| IoError::new(path, e))?;
        wr.finish().map_err(|e| IoError::new(path, e))?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn renders_series_in_their_colours_and_writes_a_png() {
        let mut p = Plot::new("test").labels("x", "y").log_x(true).log_y(true);
        p.add(Series::new("a", (1..100).map(|i| (i as f64, (i * i) as f64)).collect()));
        p.add(Series::new("b", vec![(1.0, 0.0), (2.0, 4.0), (f64::NAN, 1.0), (50.0, 9.0)]).with_markers());
        let px = p.render();
        assert_eq!(px.len(), 960 * 640 * 3);
        let has = |c: Rgb| px.chunks(3).any(|q| q == c);
        assert!(has(PALETTE[0]) && has(PALETTE[1]));
        let dir = std::env::temp_dir().join(format!("sinterdem-plot-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let f = dir.join("t.png");
        p.save_png(&f).unwrap();
        let bytes = std::fs::read(&f).unwrap();
        assert_eq!(&bytes[1..4], b"PNG");
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn ticks_cover_the_data() {
        let (a, t) = Axis::fit(0.013, 0.41, false);
        assert!(a.lo <= 0.013 && a.hi >= 0.41 && t.len() >= 3);
        let (a, t) = Axis::fit(6e-8, 5000.0, true);
        assert!(a.lo <= 6e-8 && a.hi >= 5000.0 && t.len() <= 12);
        assert_eq!(tick_label(1e-3, true, 1.0), "1e-3");
        assert_eq!(tick_label(0.25, false, 0.05), "0.25");
    }
}
