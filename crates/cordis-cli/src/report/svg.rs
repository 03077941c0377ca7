//! Inline SVG charts for the report: line charts (optionally log y, with dots for observed
//! samples) and bar charts. Colours are CSS classes, so the page's theme recolours them.

use std::fmt::Write as _;

/// One series of a line chart: `(x, y)` points, NaN y breaks the line.
pub struct Series<'a> {
    pub class: &'a str,
    pub points: Vec<(f64, f64)>,
    /// Draw the points as dots (observed samples) instead of a line.
    pub dots: bool,
}

pub struct Chart<'a> {
    pub width: f64,
    pub height: f64,
    pub x_label: &'a str,
    pub y_label: &'a str,
    pub log_y: bool,
    /// Start the y axis at 0 (errors, costs on a linear axis).
    pub y_from_zero: bool,
    pub title: &'a str,
}

impl<'a> Chart<'a> {
    /// A page-wide chart (680 × 220 px), linear y from 0: the report's residual and
    /// convergence panels.
    pub fn wide(title: &'a str, x_label: &'a str, y_label: &'a str) -> Self {
        Chart {
            width: 680.0,
            height: 220.0,
            x_label,
            y_label,
            log_y: false,
            y_from_zero: true,
            title,
        }
    }

    /// Width and height of the plotting area inside the padding, px.
    fn plot_area(&self) -> (f64, f64) {
        (
            self.width - PAD_LEFT - PAD_RIGHT,
            self.height - PAD_TOP - PAD_BOTTOM,
        )
    }
}

const PAD_LEFT: f64 = 58.0;
const PAD_RIGHT: f64 = 10.0;
const PAD_TOP: f64 = 20.0;
const PAD_BOTTOM: f64 = 34.0;

/// "Nice" ticks covering [lo, hi]: 1, 2 or 5 × 10^k steps.
fn ticks(lo: f64, hi: f64, count: usize) -> Vec<f64> {
    if hi <= lo || hi.is_nan() || lo.is_nan() {
        return vec![lo];
    }
    let raw = (hi - lo) / count.max(1) as f64;
    let mag = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 5.0, 10.0]
        .iter()
        .map(|m| m * mag)
        .find(|s| (hi - lo) / s <= count as f64 + 1.0)
        .unwrap_or(10.0 * mag);
    let mut t = (lo / step).ceil() * step;
    let mut out = Vec::new();
    while t <= hi + step * 1e-9 && out.len() < 50 {
        out.push(if t.abs() < step * 1e-9 { 0.0 } else { t });
        t += step;
    }
    out
}

fn label(v: f64) -> String {
    if v == 0.0 {
        return "0".into();
    }
    let a = v.abs();
    if (1e-3..1e5).contains(&a) {
        let s = format!("{v:.4}");
        let s = s.trim_end_matches('0').trim_end_matches('.');
        s.to_string()
    } else {
        format!("{v:.1e}")
    }
}

/// The range of the finite values, widened when flat.
fn range(values: impl Iterator<Item = f64>) -> Option<(f64, f64)> {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in values.filter(|v| v.is_finite()) {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    if lo > hi {
        return None;
    }
    if hi - lo <= 1e-12 * hi.abs().max(lo.abs()).max(1e-300) {
        let w = if hi == 0.0 { 1.0 } else { 0.05 * hi.abs() };
        return Some((lo - w, hi + w));
    }
    Some((lo, hi))
}

/// A line chart as an `<svg>` element; a note instead when no series has a finite point.
pub fn line_chart(c: &Chart, series: &[Series]) -> String {
    let ty = |y: f64| if c.log_y { y.log10() } else { y };
    let xs = range(series.iter().flat_map(|s| s.points.iter().map(|p| p.0)));
    let ys = range(
        series
            .iter()
            .flat_map(|s| s.points.iter().map(|p| p.1))
            .filter(|&y| !c.log_y || y > 0.0)
            .map(ty)
            .chain((c.y_from_zero && !c.log_y).then_some(0.0)),
    );
    let (Some((x0, x1)), Some((y0, y1))) = (xs, ys) else {
        return format!(
            "<p class=\"note\">{}: no finite value to plot.</p>",
            c.title
        );
    };
    let (w, h) = c.plot_area();
    let px = |x: f64| PAD_LEFT + (x - x0) / (x1 - x0) * w;
    let py = |y: f64| PAD_TOP + (1.0 - (ty(y) - y0) / (y1 - y0)) * h;
    let mut s = String::new();
    open_svg(&mut s, c);
    for t in ticks(x0, x1, 5) {
        let x = px(t);
        let _ = write!(
            s,
            "<line class=\"grid\" x1=\"{x:.1}\" x2=\"{x:.1}\" y1=\"{PAD_TOP}\" y2=\"{:.1}\"/>",
            PAD_TOP + h,
        );
        x_tick(&mut s, x, h, t);
    }
    for t in ticks(y0, y1, 4) {
        let y = PAD_TOP + (1.0 - (t - y0) / (y1 - y0)) * h;
        let shown = if c.log_y { 10f64.powf(t) } else { t };
        y_tick(&mut s, w, y, shown);
    }
    for se in series {
        if se.dots {
            let _ = write!(s, "<g class=\"{}\">", se.class);
            for &(x, y) in se.points.iter().filter(|p| p.1.is_finite()) {
                if c.log_y && y <= 0.0 {
                    continue;
                }
                let _ = write!(
                    s,
                    "<circle cx=\"{:.1}\" cy=\"{:.1}\" r=\"1.6\"/>",
                    px(x),
                    py(y)
                );
            }
            s.push_str("</g>");
        } else {
            let mut d = String::new();
            let mut pen_down = false;
            for &(x, y) in &se.points {
                if !y.is_finite() || (c.log_y && y <= 0.0) {
                    pen_down = false;
                    continue;
                }
                let _ = write!(
                    d,
                    "{}{:.1},{:.1}",
                    if pen_down { " L" } else { " M" },
                    px(x),
                    py(y)
                );
                pen_down = true;
            }
            let _ = write!(s, "<path class=\"{}\" d=\"{}\"/>", se.class, d.trim_start());
        }
    }
    close_svg(&mut s, c, w, h);
    s
}

/// The `<svg>` element's opening and the chart's title.
fn open_svg(s: &mut String, c: &Chart) {
    let _ = write!(
        s,
        "<svg class=\"chart\" viewBox=\"0 0 {} {}\" width=\"{}\" height=\"{}\" role=\"img\" \
         aria-label=\"{}\"><text class=\"title\" x=\"{PAD_LEFT}\" y=\"13\">{}</text>",
        c.width, c.height, c.width, c.height, c.title, c.title
    );
}

/// A horizontal grid line at height `y` (px) across a plot `w` px wide, labelled `value`.
fn y_tick(s: &mut String, w: f64, y: f64, value: f64) {
    let _ = write!(
        s,
        "<line class=\"grid\" x1=\"{PAD_LEFT}\" x2=\"{:.1}\" y1=\"{y:.1}\" y2=\"{y:.1}\"/>\
         <text class=\"tick\" x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"end\">{}</text>",
        PAD_LEFT + w,
        PAD_LEFT - 4.0,
        y + 3.5,
        label(value)
    );
}

/// A tick label under a plot `h` px high, at `x` px, reading `value`.
fn x_tick(s: &mut String, x: f64, h: f64, value: f64) {
    let _ = write!(
        s,
        "<text class=\"tick\" x=\"{x:.1}\" y=\"{:.1}\" text-anchor=\"middle\">{}</text>",
        PAD_TOP + h + 13.0,
        label(value)
    );
}

/// The axis labels under and left of a `w` × `h` px plot, and the `<svg>` element's end.
fn close_svg(s: &mut String, c: &Chart, w: f64, h: f64) {
    let _ = write!(
        s,
        "<text class=\"axis\" x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"middle\">{}</text>\
         <text class=\"axis\" transform=\"translate(12 {:.1}) rotate(-90)\" \
         text-anchor=\"middle\">{}</text></svg>",
        PAD_LEFT + w / 2.0,
        c.height - 4.0,
        c.x_label,
        PAD_TOP + h / 2.0,
        c.y_label
    );
}

/// A bar chart of `values` (one bar each, labelled by index), NaN bars left out.
pub fn bar_chart(c: &Chart, values: &[f64]) -> String {
    let Some((_, hi)) = range(values.iter().copied().chain([0.0])) else {
        return format!("<p class=\"note\">{}: no value to plot.</p>", c.title);
    };
    let (w, h) = c.plot_area();
    let n = values.len().max(1) as f64;
    let bw = w / n;
    let mut s = String::new();
    open_svg(&mut s, c);
    for t in ticks(0.0, hi, 4) {
        let y = PAD_TOP + (1.0 - t / hi) * h;
        y_tick(&mut s, w, y, t);
    }
    s.push_str("<g class=\"bar\">");
    for (i, &v) in values.iter().enumerate() {
        if !v.is_finite() {
            continue;
        }
        let bh = v / hi * h;
        let _ = write!(
            s,
            "<rect x=\"{:.2}\" y=\"{:.2}\" width=\"{:.2}\" height=\"{:.2}\"><title>particle {i}: {}</title></rect>",
            PAD_LEFT + i as f64 * bw + bw * 0.1,
            PAD_TOP + h - bh,
            (bw * 0.8).max(0.5),
            bh,
            label(v)
        );
    }
    s.push_str("</g>");
    for t in ticks(0.0, n - 1.0, 6) {
        x_tick(&mut s, PAD_LEFT + (t + 0.5) * bw, h, t);
    }
    close_svg(&mut s, c, w, h);
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_are_round_and_cover_the_range() {
        let t = ticks(0.0, 1.0, 5);
        assert_eq!((t.len(), t[0], t[5]), (6, 0.0, 1.0));
        assert_eq!(ticks(3.0, 47.0, 4), vec![10.0, 20.0, 30.0, 40.0]);
        assert_eq!(label(0.25), "0.25");
        assert_eq!(label(2.5e-7), "2.5e-7");
    }

    #[test]
    fn a_chart_of_nothing_finite_is_a_note_not_a_broken_svg() {
        let c = Chart {
            width: 300.0,
            height: 150.0,
            x_label: "t",
            y_label: "y",
            log_y: true,
            y_from_zero: false,
            title: "cost",
        };
        let s = line_chart(
            &c,
            &[Series {
                class: "model",
                points: vec![(0.0, f64::NAN), (1.0, 0.0)],
                dots: false,
            }],
        );
        assert!(
            s.starts_with("<p class=\"note\">cost: no finite value"),
            "{s}"
        );
        let s = line_chart(
            &c,
            &[Series {
                class: "model",
                points: vec![(0.0, 1.0), (1.0, f64::NAN), (2.0, 0.1)],
                dots: false,
            }],
        );
        assert!(s.contains("<path class=\"model\" d=\"M"), "{s}");
        assert_eq!(
            s.matches(" M").count() + 1,
            2,
            "the NaN breaks the line: {s}"
        );
    }
}
