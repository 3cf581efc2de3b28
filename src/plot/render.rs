//! Drawing a [`PlotSpec`](super::PlotSpec) with plotters: layout, dashes, markers, axes and legend
//! (docs/outputs.md "Plots"); every decision is in the specification, none here.

use super::*;

/// Renders a spec to an RGB buffer (row-major, 3 bytes per pixel).
pub fn render_spec(spec: &PlotSpec) -> Vec<u8> {
    let (w, h) = (spec.width, spec.height);
    let mut buf = vec![255u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        // drawing into memory cannot fail for I/O reasons; a failure leaves a partial image
        let _ = draw(spec, root, true);
    }
    buf
}

/// Renders a spec as an SVG document.
pub fn render_spec_svg(spec: &PlotSpec) -> String {
    let mut s = String::new();
    {
        let root = SVGBackend::with_string(&mut s, (spec.width, spec.height)).into_drawing_area();
        let _ = draw(spec, root, false);
    }
    // plotters writes every path as a solid polyline: the series lines (the only polylines of
    // their colour and line width) get their dash array here
    let lw = Layout::new(spec).lw;
    for sp in &spec.series {
        let Some(style) = sp.line else { continue };
        let [r, g, b] = sp.colour;
        let key = format!("stroke=\"#{r:02X}{g:02X}{b:02X}\" stroke-width=\"{lw}\" points=");
        let dash = style.svg_dasharray(Layout::new(spec).scale).map(|d| format!(" stroke-dasharray=\"{d}\"")).unwrap_or_default();
        let with = format!("stroke=\"#{r:02X}{g:02X}{b:02X}\" stroke-width=\"{lw}\"{dash} stroke-linecap=\"round\" stroke-linejoin=\"round\" points=");
        s = s.replace(&key, &with);
    }
    s
}

/// Sizes in pixels for a spec.
pub(super) struct Layout {
    scale: f64,
    /// Line width, marker outline width (never equal: the SVG dash arrays are keyed by the line
    /// width), marker radius.
    lw: u32,
    mw: u32,
    r: i32,
}

impl Layout {
    fn new(spec: &PlotSpec) -> Layout {
        let scale = (spec.height as f64 / 640.0).clamp(0.5, 3.0);
        let lw = ((2.5 * scale).round() as u32).max(1);
        let mw = if lw >= 3 { lw - 1 } else { lw + 1 };
        Layout { scale, lw, mw, r: ((5.5 * scale).round() as i32).max(3) }
    }

    fn px(&self, v: f64) -> u32 {
        (v * self.scale).round() as u32
    }
}

/// Splits a pixel polyline into the drawn pieces of a dash `pattern` (on/off lengths [px]; empty:
/// the whole line).
pub fn dash(run: &[(f64, f64)], pattern: &[f64]) -> Vec<Vec<(f64, f64)>> {
    if pattern.is_empty() || run.len() < 2 || pattern.iter().sum::<f64>() <= 0.0 {
        return vec![run.to_vec()];
    }
    let mut out = Vec::new();
    let mut cur = vec![run[0]];
    let (mut k, mut on) = (0usize, true);
    let mut left = pattern[0];
    for w in run.windows(2) {
        let (a, b) = (w[0], w[1]);
        let len = (b.0 - a.0).hypot(b.1 - a.1);
        let mut pos = 0.0;
        while len - pos > left {
            pos += left;
            let f = pos / len;
            let p = (a.0 + f * (b.0 - a.0), a.1 + f * (b.1 - a.1));
            if on {
                cur.push(p);
                out.push(std::mem::take(&mut cur));
            } else {
                cur = vec![p];
            }
            on = !on;
            k = (k + 1) % pattern.len();
            left = pattern[k];
        }
        left -= len - pos;
        if on {
            cur.push(b);
        }
    }
    if on && cur.len() >= 2 {
        out.push(cur);
    }
    out
}

/// Points at arc-length fractions `fractions` (each in [0, 1]) along pixel polylines taken as
/// one path (the gaps between them not counted).
pub(super) fn along(runs: &[Vec<(f64, f64)>], fractions: &[f64]) -> Vec<(f64, f64)> {
    let seg = |p: &[(f64, f64)]| p.windows(2).map(|w| (w[1].0 - w[0].0).hypot(w[1].1 - w[0].1)).sum::<f64>();
    let total: f64 = runs.iter().map(|r| seg(r)).sum();
    let mut out = Vec::new();
    if total <= 0.0 {
        return runs.iter().flatten().take(1).copied().collect();
    }
    for &f in fractions {
        let mut s = f.clamp(0.0, 1.0) * total;
        'find: for r in runs {
            for w in r.windows(2) {
                let l = (w[1].0 - w[0].0).hypot(w[1].1 - w[0].1);
                if s <= l && l > 0.0 {
                    let t = s / l;
                    out.push((w[0].0 + t * (w[1].0 - w[0].0), w[0].1 + t * (w[1].1 - w[0].1)));
                    break 'find;
                }
                s -= l;
            }
        }
    }
    out
}

/// Maps data to backend pixels within the plot area.
pub(super) struct Map {
    x: (f64, f64, bool),
    y: (f64, f64, bool),
    px: (f64, f64),
    py: (f64, f64),
}

impl Map {
    fn u(v: f64, log: bool) -> f64 {
        if log { v.ln() } else { v }
    }

    fn at(&self, x: f64, y: f64) -> (f64, f64) {
        let fx = (Map::u(x, self.x.2) - Map::u(self.x.0, self.x.2)) / (Map::u(self.x.1, self.x.2) - Map::u(self.x.0, self.x.2));
        let fy = (Map::u(y, self.y.2) - Map::u(self.y.0, self.y.2)) / (Map::u(self.y.1, self.y.2) - Map::u(self.y.0, self.y.2));
        (self.px.0 + fx * (self.px.1 - self.px.0), self.py.1 - fy * (self.py.1 - self.py.0))
    }
}

pub(super) fn ok(spec: &PlotSpec, x: f64, y: f64) -> bool {
    x.is_finite() && y.is_finite() && (!spec.x.log || x > 0.0) && (!spec.y.log || y > 0.0)
}

/// Drops points closer than half a pixel to the last kept one (a plot of 10⁵ rows draws as fast
/// and small as one of 10³).
pub(super) fn thin(run: &[(f64, f64)]) -> Vec<(f64, f64)> {
    let mut out: Vec<(f64, f64)> = Vec::with_capacity(run.len());
    for (k, &p) in run.iter().enumerate() {
        let last = out.last().copied().unwrap_or((f64::NAN, f64::NAN));
        if k == 0 || k + 1 == run.len() || (p.0 - last.0).hypot(p.1 - last.1) >= 0.5 {
            out.push(p);
        }
    }
    out
}

pub(super) fn ipt(p: (f64, f64)) -> (i32, i32) {
    (p.0.round() as i32, p.1.round() as i32)
}

/// Draws a pixel polyline in a style: pieces of the dash pattern with round caps on a bitmap,
/// one polyline on SVG (its dash array is added afterwards, [`render_spec_svg`]).
pub(super) fn draw_line<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    run: &[(f64, f64)],
    style: LineStyle,
    col: RGBColor,
    lay: &Layout,
    raster: bool,
) -> DrawResult<DB::ErrorType> {
    let st = ShapeStyle::from(&col).stroke_width(lay.lw);
    if !raster {
        return root.draw(&PathElement::new(run.iter().map(|&p| ipt(p)).collect::<Vec<_>>(), st));
    }
    let pattern: Vec<f64> = style.pattern().iter().map(|v| v * lay.scale).collect();
    let rad = (lay.lw as f64 / 2.0).round().max(1.0) as i32;
    for piece in dash(run, &pattern) {
        // plotters' bitmap polygonisation of a wide polyline breaks at sharp turns (histogram
        // steps): segments with round joints and caps instead
        for q in piece.windows(2) {
            root.draw(&PathElement::new(vec![ipt(q[0]), ipt(q[1])], st))?;
        }
        if lay.lw > 1 {
            for &p in &piece {
                root.draw(&Circle::new(ipt(p), rad, col.filled()))?;
            }
        }
    }
    Ok(())
}

/// Draws a marker centred at pixel `p`.
pub(super) fn draw_marker<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    p: (f64, f64),
    m: Marker,
    col: RGBColor,
    lay: &Layout,
) -> DrawResult<DB::ErrorType> {
    let r = lay.r as f64;
    let (cx, cy) = p;
    let poly = |pts: &[(f64, f64)]| pts.iter().map(|&(x, y)| ipt((cx + x * r, cy + y * r))).collect::<Vec<_>>();
    let square = [(-0.85, -0.85), (0.85, -0.85), (0.85, 0.85), (-0.85, 0.85)];
    let triangle = [(0.0, -1.2), (1.1, 0.75), (-1.1, 0.75)];
    let diamond = [(0.0, -1.25), (1.1, 0.0), (0.0, 1.25), (-1.1, 0.0)];
    let outline = ShapeStyle::from(&col).stroke_width(lay.mw);
    let open = |pts: &[(f64, f64)]| -> DrawResult<DB::ErrorType> {
        let v = poly(pts);
        root.draw(&Polygon::new(v.clone(), WHITE.filled()))?;
        let mut closed = v.clone();
        closed.push(v[0]);
        root.draw(&PathElement::new(closed, outline))
    };
    match m {
        Marker::Circle => root.draw(&Circle::new(ipt(p), lay.r, col.filled())),
        Marker::Square => root.draw(&Polygon::new(poly(&square), col.filled())),
        Marker::Triangle => root.draw(&Polygon::new(poly(&triangle), col.filled())),
        Marker::Diamond => root.draw(&Polygon::new(poly(&diamond), col.filled())),
        Marker::OpenCircle => {
            root.draw(&Circle::new(ipt(p), lay.r, WHITE.filled()))?;
            root.draw(&Circle::new(ipt(p), lay.r, outline))
        }
        Marker::OpenSquare => open(&square),
        Marker::OpenTriangle => open(&triangle),
        Marker::OpenDiamond => open(&diamond),
    }
}

/// The subtitle as drawn: one line, or two split at the "; " (else ", ") nearest its middle when
/// one line would need a font below 80 % of `size` [px] in the width `w` [px].
pub(super) fn subtitle_lines(sub: &str, w: f64, size: f64) -> Vec<String> {
    let n = sub.chars().count();
    if sub.is_empty() {
        return Vec::new();
    }
    if 0.56 * size * 0.8 * n as f64 <= 0.95 * w {
        return vec![sub.to_string()];
    }
    let mid = sub.len() / 2;
    let split = ["; ", ", "].iter().find_map(|sep| sub.match_indices(sep).map(|(i, _)| i).min_by_key(|&i| i.abs_diff(mid)).map(|i| (i, sep.len())));
    match split {
        Some((i, l)) => vec![sub[..i + l.min(1)].trim_end().to_string(), sub[i + l..].to_string()],
        None => vec![sub.to_string()],
    }
}

/// The title, subtitle, axes and series of a spec.
pub(super) fn draw<DB: DrawingBackend>(spec: &PlotSpec, root: DrawingArea<DB, Shift>, raster: bool) -> DrawResult<DB::ErrorType> {
    font();
    root.fill(&WHITE)?;
    let lay = Layout::new(spec);
    let w = spec.width;
    // title and subtitle, each shrunk to fit the width
    let fit = |text: &str, size: f64| -> f64 { size.min(0.95 * w as f64 / (0.56 * text.chars().count().max(1) as f64)) };
    let title_size = fit(&spec.title, lay.scale * 24.0);
    let sub_lines = subtitle_lines(&spec.subtitle, w as f64, lay.scale * 17.0);
    let mut head = lay.px(8.0) as i32;
    if !spec.title.is_empty() {
        let st = TextStyle::from(("sans-serif", title_size).into_font()).pos(Pos::new(HPos::Center, VPos::Top));
        root.draw_text(&spec.title, &st, (w as i32 / 2, head))?;
        head += (title_size * 1.3) as i32;
    }
    for line in &sub_lines {
        let size = fit(line, lay.scale * 17.0);
        let st = TextStyle::from(("sans-serif", size).into_font()).color(&RGBColor(70, 70, 70)).pos(Pos::new(HPos::Center, VPos::Top));
        root.draw_text(line, &st, (w as i32 / 2, head))?;
        head += (size * 1.35) as i32;
    }
    let (_, body) = root.split_vertically(head + lay.px(4.0) as i32);
    let ((x0, x1), (y0, y1)) = (spec.x.range, spec.y.range);
    match (spec.x.log, spec.y.log) {
        (false, false) => chart(spec, &root, &body, x0..x1, y0..y1, raster, &lay),
        (true, false) => chart(spec, &root, &body, (x0..x1).log_scale(), y0..y1, raster, &lay),
        (false, true) => chart(spec, &root, &body, x0..x1, (y0..y1).log_scale(), raster, &lay),
        (true, true) => chart(spec, &root, &body, (x0..x1).log_scale(), (y0..y1).log_scale(), raster, &lay),
    }?;
    root.present()
}

/// Rows of named x ticks so that neighbours do not overlap (1 to 3), given the slot width [px].
pub(super) fn tick_rows(ticks: &[(f64, String)], slot: f64, char_px: f64) -> usize {
    let widest = ticks.iter().map(|t| t.1.chars().count()).max().unwrap_or(1) as f64 * char_px + char_px;
    ((widest / slot.max(1.0)).ceil() as usize).clamp(1, 3)
}

#[allow(clippy::too_many_arguments)]
pub(super) fn chart<DB, X, Y>(
    spec: &PlotSpec,
    root: &DrawingArea<DB, Shift>,
    body: &DrawingArea<DB, Shift>,
    xr: X,
    yr: Y,
    raster: bool,
    lay: &Layout,
) -> DrawResult<DB::ErrorType>
where
    DB: DrawingBackend,
    X: plotters::coord::ranged1d::AsRangedCoord<Value = f64>,
    Y: plotters::coord::ranged1d::AsRangedCoord<Value = f64>,
    X::CoordDescType: plotters::coord::ranged1d::ValueFormatter<f64>,
    Y::CoordDescType: plotters::coord::ranged1d::ValueFormatter<f64>,
{
    let w = spec.width;
    let px = |v: f64| lay.px(v);
    let tick_font = ("sans-serif", px(17.0) as f64);
    let label_font = ("sans-serif", px(20.0) as f64);
    // room for the widest y tick label (≈ 0.6 em per character) plus the rotated axis title
    let (ylo, yhi) = spec.y.range;
    let widest = [ylo, yhi, 0.5 * (ylo + yhi), -ylo.abs().max(yhi.abs())].iter().map(|&v| tick_label(v).chars().count()).max().unwrap_or(4).max(4);
    let y_area = px(17.0 * 0.62 * widest as f64 + 44.0);
    let named = !spec.x.ticks.is_empty();
    // named ticks: one row per level of staggering
    let approx_plot_w = w as f64 - y_area as f64 - px(38.0) as f64;
    let slot = approx_plot_w / (spec.x.range.1 - spec.x.range.0).max(1.0);
    let rows = if named { tick_rows(&spec.x.ticks, slot, 15.0 * lay.scale * 0.6) } else { 1 };
    let x_area = px(62.0) + if named { px(20.0) * (rows as u32 - 1) } else { 0 };
    let mut chart = ChartBuilder::on(body)
        .margin_top(px(6.0))
        .margin_left(px(10.0))
        .margin_right(px(28.0))
        .margin_bottom(px(10.0))
        .x_label_area_size(x_area)
        .y_label_area_size(y_area)
        .build_cartesian_2d(xr, yr)?;
    let span = |a: &AxisSpec| if a.log { 0.0 } else { (a.range.1 - a.range.0).abs() };
    let (sx, sy) = (span(&spec.x), span(&spec.y));
    let top = |a: &AxisSpec| if a.log { 0.0 } else { a.range.0.abs().max(a.range.1.abs()) };
    let (mx, my) = (top(&spec.x), top(&spec.y));
    let fmt_y = move |v: &f64| tick_label_on(snap_zero(*v, sy), my);
    let fmt = move |v: &f64| tick_label_on(snap_zero(*v, sx), mx);
    let blank = |_: &f64| String::new();
    let mut mesh = chart.configure_mesh();
    mesh.x_desc(spec.x.label.as_str())
        .y_desc(spec.y.label.as_str())
        .axis_desc_style(label_font)
        .label_style(tick_font)
        .y_label_formatter(&fmt_y)
        .y_labels(8)
        .light_line_style(RGBColor(240, 240, 240))
        .bold_line_style(RGBColor(215, 215, 215));
    if named {
        mesh.x_label_formatter(&blank).x_labels(0);
    } else {
        mesh.x_label_formatter(&fmt).x_labels(if w >= 700 { 9 } else { 5 });
    }
    mesh.draw()?;
    let (xpix, ypix) = chart.plotting_area().get_pixel_range();
    let map = Map {
        x: (spec.x.range.0, spec.x.range.1, spec.x.log),
        y: (spec.y.range.0, spec.y.range.1, spec.y.log),
        px: (xpix.start as f64, (xpix.end - 1) as f64),
        py: (ypix.start as f64, (ypix.end - 1) as f64),
    };
    if named {
        let f = px(15.0) as f64;
        let st = TextStyle::from(("sans-serif", f).into_font()).pos(Pos::new(HPos::Center, VPos::Top));
        for (k, (x, name)) in spec.x.ticks.iter().enumerate() {
            let (tx, _) = map.at(*x, spec.y.range.0.max(if spec.y.log { f64::MIN_POSITIVE } else { f64::NEG_INFINITY }));
            let base = ypix.end;
            let row = (k % rows) as i32;
            root.draw(&PathElement::new(
                vec![(tx.round() as i32, base), (tx.round() as i32, base + px(5.0) as i32 + row * px(20.0) as i32)],
                ShapeStyle::from(&RGBColor(120, 120, 120)).stroke_width(1),
            ))?;
            root.draw_text(name, &st, (tx.round() as i32, base + px(7.0) as i32 + row * px(20.0) as i32))?;
        }
    }
    for s in &spec.series {
        let col = RGBColor(s.colour[0], s.colour[1], s.colour[2]);
        // runs of drawable points in pixels: a skipped point breaks the line
        let mut runs: Vec<Vec<(f64, f64)>> = vec![Vec::new()];
        for &(x, y) in &s.points {
            if ok(spec, x, y) {
                runs.last_mut().expect("one run").push(map.at(x, y));
            } else if !runs.last().expect("one run").is_empty() {
                runs.push(Vec::new());
            }
        }
        let runs: Vec<Vec<(f64, f64)>> = runs.into_iter().filter(|r| !r.is_empty()).map(|r| thin(&r)).collect();
        if let Some(style) = s.line {
            for run in &runs {
                draw_line(root, run, style, col, lay, raster)?;
            }
        }
        if !s.error_bars.is_empty() {
            let st = ShapeStyle::from(&col).stroke_width(lay.mw);
            let cap = px(6.0) as i32;
            for (&(x, y), &e) in s.points.iter().zip(&s.error_bars) {
                if !ok(spec, x, y) || !e.is_finite() {
                    continue;
                }
                let lo = if spec.y.log && y - e.abs() <= 0.0 { y } else { y - e.abs() };
                let (a, b) = (ipt(map.at(x, lo)), ipt(map.at(x, y + e.abs())));
                root.draw(&PathElement::new(vec![a, b], st))?;
                for q in [a, b] {
                    root.draw(&PathElement::new(vec![(q.0 - cap, q.1), (q.0 + cap, q.1)], st))?;
                }
            }
        }
        if let Some(m) = s.marker {
            let at: Vec<(f64, f64)> = match s.placement {
                MarkerPlacement::None => Vec::new(),
                MarkerPlacement::Every => s.points.iter().filter(|&&(x, y)| ok(spec, x, y)).map(|&(x, y)| map.at(x, y)).collect(),
                MarkerPlacement::Staggered { phase, count } => along(&runs, &(0..count).map(|j| (j as f64 + phase) / count as f64).collect::<Vec<_>>()),
            };
            for p in at {
                draw_marker(root, p, m, col, lay)?;
            }
        }
    }
    if spec.legend {
        legend(spec, root, &map, lay, raster)?;
    }
    Ok(())
}

/// The legend box at the spot of the plot area that hides the least ink (markers and lines, see
/// [`legend_spot`]): per named series a line sample in its style with its marker, and the name.
pub(super) fn legend<DB: DrawingBackend>(spec: &PlotSpec, root: &DrawingArea<DB, Shift>, map: &Map, lay: &Layout, raster: bool) -> DrawResult<DB::ErrorType> {
    let entries: Vec<&SeriesSpec> = spec.series.iter().filter(|s| !s.name.is_empty()).collect();
    let fsize = lay.px(16.0) as f64;
    let st = TextStyle::from(("sans-serif", fsize).into_font()).pos(Pos::new(HPos::Left, VPos::Center));
    let mut text_w = 0u32;
    for e in &entries {
        text_w = text_w.max(root.estimate_text_size(&e.name, &st)?.0);
    }
    let (sample, pad, row) = (lay.px(44.0) as f64, lay.px(10.0) as f64, (fsize * 1.45).round());
    let bw = pad * 3.0 + sample + text_w as f64;
    let bh = pad * 2.0 + row * entries.len() as f64;
    let (l, r, t, b) = (map.px.0, map.px.1, map.py.0, map.py.1);
    let m = lay.px(12.0) as f64;
    let lines: Vec<(bool, Vec<(f64, f64)>)> =
        spec.series.iter().map(|s| (s.line.is_some(), s.points.iter().filter(|&&(x, y)| ok(spec, x, y)).map(|&(x, y)| map.at(x, y)).collect())).collect();
    let (bx, by) = legend_spot(&ink(&lines, 3.0), (l, r, t, b), m, (bw, bh));
    root.draw(&Rectangle::new([ipt((bx, by)), ipt((bx + bw, by + bh))], RGBColor(252, 252, 252).filled()))?;
    root.draw(&Rectangle::new([ipt((bx, by)), ipt((bx + bw, by + bh))], ShapeStyle::from(&RGBColor(160, 160, 160)).stroke_width(1)))?;
    for (k, e) in entries.iter().enumerate() {
        let col = RGBColor(e.colour[0], e.colour[1], e.colour[2]);
        let y = by + pad + row * (k as f64 + 0.5);
        let (x0, x1) = (bx + pad, bx + pad + sample);
        if let Some(style) = e.line {
            draw_line(root, &[(x0, y), (x1, y)], style, col, lay, raster)?;
        }
        if let Some(mk) = e.marker {
            draw_marker(root, (0.5 * (x0 + x1), y), mk, col, lay)?;
        }
        root.draw_text(&e.name, &st, ipt((x1 + pad, y)))?;
    }
    Ok(())
}

/// A tick value of a linear axis of width `span` that is zero but for rounding in the tick
/// arithmetic (plotters steps from the range's start: −2.2e-16 instead of 0) reads as 0;
/// `span` = 0 (log axes) leaves `v` as it is.
pub(super) fn snap_zero(v: f64, span: f64) -> f64 {
    if v.abs() < 1e-9 * span { 0.0 } else { v }
}

/// Pixels a plot inks: every point, and along a series drawn with a line one sample every `step`
/// pixels of each segment (a legend placed by points alone could cover a line between them).
pub(super) fn ink(series: &[(bool, Vec<(f64, f64)>)], step: f64) -> Vec<(f64, f64)> {
    let mut out = Vec::new();
    for (line, pts) in series {
        out.extend_from_slice(pts);
        if !line {
            continue;
        }
        for w in pts.windows(2) {
            let (d, e) = ((w[1].0 - w[0].0), (w[1].1 - w[0].1));
            let n = ((d.hypot(e) / step).ceil() as usize).min(10_000);
            out.extend((1..n).map(|k| (w[0].0 + d * k as f64 / n as f64, w[0].1 + e * k as f64 / n as f64)));
        }
    }
    out
}

/// Where the legend box of `size` (w, h) [px] goes inside the plot area (l, r, t, b) [px] with
/// margin `m`: of the four corners (top right first), then the top and bottom centres, the spot
/// whose box (grown by 6 px) holds the fewest inked pixels; ties go to the earlier spot.
pub(super) fn legend_spot(ink: &[(f64, f64)], (l, r, t, b): (f64, f64, f64, f64), m: f64, (bw, bh): (f64, f64)) -> (f64, f64) {
    let cx = 0.5 * (l + r - bw);
    let spots = [(r - m - bw, t + m), (l + m, t + m), (r - m - bw, b - m - bh), (l + m, b - m - bh), (cx, t + m), (cx, b - m - bh)];
    let hidden = |&(x, y): &(f64, f64)| ink.iter().filter(|&&(u, v)| u >= x - 6.0 && u <= x + bw + 6.0 && v >= y - 6.0 && v <= y + bh + 6.0).count();
    spots.iter().copied().min_by_key(hidden).unwrap_or(spots[0])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_tick_at_zero_but_for_rounding_reads_0() {
        // the smallest-force plot: y from -1.1 to 0.02 N, plotters' top tick -2.22e-16
        assert_eq!(tick_label(snap_zero(-2.220446049250313e-16, 1.12)), "0");
        assert_eq!(tick_label(snap_zero(-0.2, 1.12)), "-0.2");
        // a log axis (span 0) keeps its small values
        assert_eq!(tick_label(snap_zero(1e-20, 0.0)), "1e-20");
        // a linear axis of tiny values keeps them: 1e-20 on a span of 1e-19
        assert_eq!(tick_label(snap_zero(1e-20, 1e-19)), "1e-20");
        // one form per axis: 5e4 beside 2.5e5 (the sintering-stress axis), plain below 1e5
        assert_eq!(tick_label_on(50000.0, 2.9e5), "5e4");
        assert_eq!(tick_label_on(250000.0, 2.9e5), "2.5e5");
        assert_eq!(tick_label_on(50000.0, 9e4), "50000");
    }

    #[test]
    fn the_legend_avoids_lines_not_only_points() {
        // a plot area 0..600 x 0..400 px whose data fill all four corners with vertices and cross
        // the bottom centre only with lines: the old rule (vertices only) picked a corner hiding a
        // vertex; now the top centre, where nothing is drawn
        let frame = (0.0, 600.0, 0.0, 400.0);
        let corners = vec![(20.0, 20.0), (580.0, 20.0), (20.0, 380.0), (580.0, 380.0)];
        // a line through the bottom centre from the bottom-left vertex to the bottom-right one
        let series = vec![(true, vec![(20.0, 380.0), (300.0, 370.0), (580.0, 380.0)]), (false, corners)];
        let spot = legend_spot(&ink(&series, 3.0), frame, 10.0, (150.0, 60.0));
        assert_eq!(spot, (225.0, 10.0), "top centre");
        // the bottom centre holds one vertex only, but its line samples count: 150 px of line at one
        // sample per 3 px is about 50 inked pixels
        let bottom = ink(&series, 3.0).iter().filter(|&&(u, v)| (219.0..=381.0).contains(&u) && (324.0..=396.0).contains(&v)).count();
        assert!((50..=56).contains(&bottom), "{bottom}");
        // without a line (markers only) the same vertices leave the bottom centre all but empty
        let markers = vec![(false, vec![(20.0, 380.0), (300.0, 370.0), (580.0, 380.0)])];
        assert_eq!(ink(&markers, 3.0).len(), 3);
    }
}
