//! A small SVG line-chart writer for the benches: a grid of panels, each with its own axes
//! (linear or logarithmic), one polyline per series and a label beside every point.
//! Hand-written so that the benches need no plotting dependency; the output is plain SVG
//! 1.1, readable in a browser and diffable in git. The same chart is also drawn as PNG
//! (by resvg, with fonts of our own) for viewers that do not show SVG.

use std::fmt::Write as _;
use std::path::Path;

use crate::error::Error;
use crate::fsutil::OutputSet;

/// The PNG's fonts, built in: system fonts differ between machines (or are missing, and
/// resvg then leaves text out without a word). DejaVu Sans, subset to Latin-1 and some
/// punctuation (host/assets/fonts/LICENSE).
const FONTS: [&[u8]; 2] = [
    include_bytes!("../../assets/fonts/DejaVuSans.ttf"),
    include_bytes!("../../assets/fonts/DejaVuSans-Bold.ttf"),
];
const FONT_FAMILY: &str = "DejaVu Sans";

/// One axis of a panel.
#[derive(Clone, Debug, Default)]
pub struct Axis {
    pub label: String,
    /// Logarithmic (base 10): values <= 0 cannot be drawn and are left out.
    pub log: bool,
    /// Tick labels as percentages of the value (0.05 shows as 5%).
    pub percent: bool,
    /// A fixed range instead of the data's (e.g. 0..1 for a fraction).
    pub range: Option<(f64, f64)>,
}

#[derive(Clone, Debug)]
pub struct ChartPoint {
    pub x: f64,
    pub y: f64,
    /// Shown beside the point (empty for none).
    pub label: String,
}

/// A curve: its points are joined in the given order.
#[derive(Clone, Debug)]
pub struct Series {
    pub name: String,
    pub points: Vec<ChartPoint>,
}

#[derive(Clone, Debug)]
pub struct Panel {
    pub title: String,
    pub x: Axis,
    pub y: Axis,
    pub series: Vec<Series>,
}

#[derive(Clone, Debug)]
pub struct Chart {
    pub title: String,
    /// Panels per row.
    pub columns: usize,
    pub panels: Vec<Panel>,
}

const PALETTE: [&str; 8] = [
    "#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2", "#17becf",
];
const LEFT: f64 = 70.0;
const TOP: f64 = 34.0;
const PLOT_W: f64 = 400.0;
const PLOT_H: f64 = 240.0;
const LEGEND_W: f64 = 150.0;
const PANEL_W: f64 = LEFT + PLOT_W + LEGEND_W;
const PANEL_H: f64 = TOP + PLOT_H + 56.0;
const HEADER: f64 = 36.0;

/// The mapping of one axis from data values to [0, 1].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Scale {
    /// Ends, in log10 units for a log axis.
    lo: f64,
    hi: f64,
    log: bool,
    /// The tick step of a linear axis.
    step: f64,
}

impl Scale {
    /// The scale that shows `values` (or the axis' fixed range): whole decades on a log
    /// axis, "nice" round ends on a linear one.
    pub fn new(axis: &Axis, values: impl IntoIterator<Item = f64>) -> Scale {
        let drawable = |v: &f64| v.is_finite() && (!axis.log || *v > 0.0);
        let (min, max) = match axis.range {
            Some((a, b)) if drawable(&a) && drawable(&b) && a < b => (a, b),
            _ => values
                .into_iter()
                .filter(drawable)
                .fold(None, |acc: Option<(f64, f64)>, v| {
                    Some(acc.map_or((v, v), |(lo, hi)| (lo.min(v), hi.max(v))))
                })
                .unwrap_or(if axis.log { (1.0, 10.0) } else { (0.0, 1.0) }),
        };
        if axis.log {
            let lo = libm::log10(min).floor();
            let hi = libm::log10(max).ceil();
            return Scale {
                lo,
                hi: if hi > lo { hi } else { lo + 1.0 },
                log: true,
                step: 0.0,
            };
        }
        if axis.range.is_some() {
            return Scale {
                lo: min,
                hi: max,
                log: false,
                step: nice_step(max - min),
            };
        }
        let (min, max) = if max > min {
            (min, max)
        } else {
            let pad = if min == 0.0 { 0.5 } else { 0.1 * min.abs() };
            (min - pad, max + pad)
        };
        let step = nice_step(max - min);
        Scale {
            lo: (min / step).floor() * step,
            hi: (max / step).ceil() * step,
            log: false,
            step,
        }
    }

    /// The position of `v` along the axis in [0, 1]; `None` if it cannot be drawn.
    pub fn t(&self, v: f64) -> Option<f64> {
        if !v.is_finite() || (self.log && v <= 0.0) {
            return None;
        }
        let u = if self.log { libm::log10(v) } else { v };
        Some((u - self.lo) / (self.hi - self.lo))
    }

    /// Tick values: each decade (with 2 and 5 when there are few) or each nice step.
    pub fn ticks(&self) -> Vec<f64> {
        if self.log {
            let few = self.hi - self.lo <= 2.0;
            let mut ticks = Vec::new();
            let mut k = self.lo;
            while k <= self.hi + 1e-9 {
                let decade = libm::pow(10.0, k);
                ticks.push(decade);
                if few && k < self.hi - 1e-9 {
                    ticks.extend([2.0 * decade, 5.0 * decade]);
                }
                k += 1.0;
            }
            return ticks;
        }
        // Multiples of the step within the ends.
        let first = (self.lo / self.step - 1e-9).ceil() as i64;
        let last = (self.hi / self.step + 1e-9).floor() as i64;
        (first..=last).map(|k| k as f64 * self.step).collect()
    }
}

/// A step of 1, 2 or 5 times a power of ten that cuts `span` into about five parts.
fn nice_step(span: f64) -> f64 {
    let raw = (span / 5.0).max(f64::MIN_POSITIVE);
    let magnitude = libm::pow(10.0, libm::log10(raw).floor());
    let unit = [1.0, 2.0, 5.0, 10.0]
        .into_iter()
        .find(|&u| u * magnitude >= raw * (1.0 - 1e-9))
        .unwrap_or(10.0);
    unit * magnitude
}

/// A tick label: six significant digits at most, no float dust.
fn tick_label(v: f64, percent: bool) -> String {
    let v = if percent { 100.0 * v } else { v };
    if v == 0.0 {
        return if percent { "0%".into() } else { "0".into() };
    }
    let digits = 5 - libm::log10(v.abs()).floor() as i32;
    let scale = libm::pow(10.0, digits.clamp(-300, 300) as f64);
    let rounded = (v * scale).round() / scale;
    if percent {
        format!("{rounded}%")
    } else {
        format!("{rounded}")
    }
}

/// Text escaped for SVG content and attribute values.
pub fn escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            c => out.push(c),
        }
    }
    out
}

impl Chart {
    /// The chart as an SVG document.
    pub fn to_svg(&self) -> String {
        let columns = self.columns.max(1);
        let rows = self.panels.len().div_ceil(columns).max(1);
        let width = columns as f64 * PANEL_W;
        let height = HEADER + rows as f64 * PANEL_H;
        let mut s = String::new();
        let _ = writeln!(
            s,
            r#"<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" viewBox="0 0 {width} {height}" font-family="sans-serif" font-size="11">"#
        );
        let _ = writeln!(
            s,
            r#"<rect width="{width}" height="{height}" fill="white"/>"#
        );
        let _ = writeln!(
            s,
            r#"<text x="{}" y="22" text-anchor="middle" font-size="15" font-weight="bold">{}</text>"#,
            width / 2.0,
            escape(&self.title)
        );
        for (i, panel) in self.panels.iter().enumerate() {
            let ox = (i % columns) as f64 * PANEL_W;
            let oy = HEADER + (i / columns) as f64 * PANEL_H;
            panel_svg(&mut s, panel, ox, oy);
        }
        s.push_str("</svg>\n");
        s
    }
}

impl Chart {
    /// The chart drawn as a PNG image of the SVG's size.
    pub fn to_png(&self) -> Result<Vec<u8>, String> {
        use resvg::{tiny_skia, usvg};
        let mut options = usvg::Options {
            font_family: FONT_FAMILY.into(),
            ..usvg::Options::default()
        };
        let fonts = options.fontdb_mut();
        for font in FONTS {
            fonts.load_font_data(font.to_vec());
        }
        fonts.set_sans_serif_family(FONT_FAMILY);
        let tree = usvg::Tree::from_str(&self.to_svg(), &options).map_err(|e| e.to_string())?;
        let size = tree.size().to_int_size();
        let mut pixmap = tiny_skia::Pixmap::new(size.width(), size.height())
            .ok_or_else(|| format!("a chart of {}x{} pixels", size.width(), size.height()))?;
        resvg::render(&tree, tiny_skia::Transform::default(), &mut pixmap.as_mut());
        pixmap.encode_png().map_err(|e| e.to_string())
    }

    /// Adds the chart to `set` as SVG at `svg` and as PNG beside it (the same name, `.png`).
    pub fn add_to(&self, set: &mut OutputSet, svg: &Path) -> Result<(), Error> {
        set.add(svg, self.to_svg().as_bytes())?;
        let png = svg.with_extension("png");
        let bytes = self.to_png().map_err(|e| Error::Io {
            file: png.clone(),
            source: std::io::Error::other(format!("drawing the chart: {e}")),
        })?;
        set.add(&png, &bytes)
    }
}

fn panel_svg(s: &mut String, panel: &Panel, ox: f64, oy: f64) {
    let points = || panel.series.iter().flat_map(|se| se.points.iter());
    let sx = Scale::new(&panel.x, points().map(|p| p.x));
    let sy = Scale::new(&panel.y, points().map(|p| p.y));
    let (x0, y0) = (ox + LEFT, oy + TOP);
    let px = |v: f64| sx.t(v).map(|t| x0 + t * PLOT_W);
    let py = |v: f64| sy.t(v).map(|t| y0 + (1.0 - t) * PLOT_H);
    let _ = writeln!(
        s,
        r#"<text x="{}" y="{}" text-anchor="middle" font-size="13" font-weight="bold">{}</text>"#,
        x0 + PLOT_W / 2.0,
        oy + 20.0,
        escape(&panel.title)
    );
    for v in sx.ticks() {
        if let Some(x) = px(v) {
            let _ = writeln!(
                s,
                r##"<line x1="{x:.1}" y1="{y0}" x2="{x:.1}" y2="{}" stroke="#e4e4e4"/><text x="{x:.1}" y="{}" text-anchor="middle">{}</text>"##,
                y0 + PLOT_H,
                y0 + PLOT_H + 15.0,
                escape(&tick_label(v, panel.x.percent))
            );
        }
    }
    for v in sy.ticks() {
        if let Some(y) = py(v) {
            let _ = writeln!(
                s,
                r##"<line x1="{x0}" y1="{y:.1}" x2="{}" y2="{y:.1}" stroke="#e4e4e4"/><text x="{}" y="{:.1}" text-anchor="end">{}</text>"##,
                x0 + PLOT_W,
                x0 - 5.0,
                y + 4.0,
                escape(&tick_label(v, panel.y.percent))
            );
        }
    }
    let _ = writeln!(
        s,
        r##"<rect x="{x0}" y="{y0}" width="{PLOT_W}" height="{PLOT_H}" fill="none" stroke="#888"/>"##
    );
    let _ = writeln!(
        s,
        r#"<text x="{}" y="{}" text-anchor="middle">{}</text>"#,
        x0 + PLOT_W / 2.0,
        y0 + PLOT_H + 34.0,
        escape(&panel.x.label)
    );
    let _ = writeln!(
        s,
        r#"<text transform="translate({},{}) rotate(-90)" text-anchor="middle">{}</text>"#,
        ox + 16.0,
        y0 + PLOT_H / 2.0,
        escape(&panel.y.label)
    );
    if points().all(|p| px(p.x).is_none() || py(p.y).is_none()) {
        let _ = writeln!(
            s,
            r##"<text x="{}" y="{}" text-anchor="middle" fill="#888">no data</text>"##,
            x0 + PLOT_W / 2.0,
            y0 + PLOT_H / 2.0
        );
    }
    for (i, series) in panel.series.iter().enumerate() {
        let colour = PALETTE[i % PALETTE.len()];
        let drawn: Vec<(f64, f64, &str)> = series
            .points
            .iter()
            .filter_map(|p| Some((px(p.x)?, py(p.y)?, p.label.as_str())))
            .collect();
        if drawn.len() >= 2 {
            let coords: Vec<String> = drawn
                .iter()
                .map(|(x, y, _)| format!("{x:.1},{y:.1}"))
                .collect();
            let _ = writeln!(
                s,
                r#"<polyline points="{}" fill="none" stroke="{colour}" stroke-width="1.6"/>"#,
                coords.join(" ")
            );
        }
        for (x, y, label) in &drawn {
            let _ = writeln!(
                s,
                r#"<circle cx="{x:.1}" cy="{y:.1}" r="3" fill="{colour}"/>"#
            );
            if !label.is_empty() {
                let _ = writeln!(
                    s,
                    r#"<text x="{:.1}" y="{:.1}" font-size="9" fill="{colour}">{}</text>"#,
                    x + 4.0,
                    y - 4.0,
                    escape(label)
                );
            }
        }
        let ly = y0 + 8.0 + 16.0 * i as f64;
        let lx = x0 + PLOT_W + 12.0;
        let _ = writeln!(
            s,
            r#"<line x1="{lx}" y1="{ly}" x2="{}" y2="{ly}" stroke="{colour}" stroke-width="2"/><text x="{}" y="{}">{}</text>"#,
            lx + 18.0,
            lx + 22.0,
            ly + 4.0,
            escape(&series.name)
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn axis(log: bool) -> Axis {
        Axis {
            label: "x".into(),
            log,
            ..Axis::default()
        }
    }

    fn series(name: &str, xy: &[(f64, f64)]) -> Series {
        Series {
            name: name.into(),
            points: xy
                .iter()
                .map(|&(x, y)| ChartPoint {
                    x,
                    y,
                    label: format!("{x}"),
                })
                .collect(),
        }
    }

    /// The dark pixels of a decoded PNG in rows `rows`.
    fn dark_pixels(png: &[u8], rows: std::ops::Range<u32>) -> usize {
        let image = image::load_from_memory(png).unwrap().to_rgb8();
        rows.flat_map(|y| (0..image.width()).map(move |x| (x, y)))
            .filter(|&(x, y)| image.get_pixel(x, y).0.iter().all(|&c| c < 128))
            .count()
    }

    #[test]
    fn the_png_is_the_svgs_size_and_draws_its_text_with_our_fonts() {
        let chart = |title: &str| Chart {
            title: title.into(),
            columns: 2,
            panels: vec![Panel {
                title: String::new(),
                x: axis(true),
                y: axis(false),
                series: vec![series("a", &[(1.0, 2.0), (10.0, 3.0)])],
            }],
        };
        let titled = chart("relume bench tradeoff: glossy").to_png().unwrap();
        let image = image::load_from_memory(&titled).unwrap();
        assert_eq!(
            (image.width(), image.height()),
            ((2.0 * PANEL_W) as u32, (HEADER + PANEL_H) as u32)
        );
        // The title's band: text in the titled chart, nothing in the untitled one.
        let band = 6..HEADER as u32;
        let untitled = chart("").to_png().unwrap();
        assert_eq!(dark_pixels(&untitled, band.clone()), 0);
        assert!(dark_pixels(&titled, band) > 200, "the title is drawn");
    }

    #[test]
    fn log_scale_spans_whole_decades_evenly() {
        let s = Scale::new(&axis(true), [0.013, 0.9, -1.0, 0.0]);
        assert!((s.t(0.01).unwrap()).abs() < 1e-12);
        assert!((s.t(0.1).unwrap() - 0.5).abs() < 1e-12);
        assert!((s.t(1.0).unwrap() - 1.0).abs() < 1e-12);
        assert_eq!(s.t(0.0), None);
        assert_eq!(s.ticks(), vec![0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0]);
    }

    #[test]
    fn linear_scale_has_round_ends_and_steps() {
        let s = Scale::new(&axis(false), [0.03, 0.93]);
        let ticks = s.ticks();
        assert_eq!(ticks.len(), 6, "{ticks:?}");
        assert!((ticks[0] - 0.0).abs() < 1e-12 && (ticks[5] - 1.0).abs() < 1e-12);
        let fixed = Scale::new(
            &Axis {
                range: Some((0.0, 1.0)),
                ..axis(false)
            },
            [0.5, 0.6],
        );
        assert_eq!((fixed.t(0.0), fixed.t(1.0)), (Some(0.0), Some(1.0)));
        // One value: a range around it, not a division by zero.
        let one = Scale::new(&axis(false), [2.0]);
        assert!(one.t(2.0).unwrap() > 0.0 && one.t(2.0).unwrap() < 1.0);
        // Ticks are multiples of the step, zero included, on either side of it.
        let signed = Scale::new(&axis(false), [-5.0, 5.0]);
        assert!(signed.ticks().contains(&0.0), "{:?}", signed.ticks());
        assert!(signed.ticks().iter().all(|t| (t / 2.0).fract() == 0.0));
    }

    #[test]
    fn tick_labels_have_no_float_dust() {
        assert_eq!(tick_label(0.1 + 0.2, false), "0.3");
        assert_eq!(tick_label(0.05, true), "5%");
        assert_eq!(tick_label(0.0, true), "0%");
        assert_eq!(tick_label(1000.0, false), "1000");
    }

    #[test]
    fn svg_has_a_polyline_per_curve_escaped_text_and_skips_undrawable_points() {
        let chart = Chart {
            title: "a<b & c".into(),
            columns: 2,
            panels: vec![
                Panel {
                    title: "errors".into(),
                    x: axis(true),
                    y: axis(true),
                    series: vec![
                        series("one", &[(1.0, 0.0), (2.0, 0.1), (4.0, 0.05)]),
                        series("two", &[(1.0, 0.2), (10.0, 0.3)]),
                        series("lonely", &[(3.0, 0.2)]),
                    ],
                },
                Panel {
                    title: "empty".into(),
                    x: axis(false),
                    y: axis(true),
                    series: vec![],
                },
            ],
        };
        let svg = chart.to_svg();
        assert!(svg.starts_with("<svg ") && svg.trim_end().ends_with("</svg>"));
        assert!(svg.contains("a&lt;b &amp; c") && !svg.contains("a<b"));
        assert_eq!(svg.matches("<polyline").count(), 2);
        // "one" lost its y = 0 point on the log axis: two coordinates remain.
        let first = svg.split("<polyline points=\"").nth(1).unwrap();
        let coords = first.split('"').next().unwrap();
        assert_eq!(coords.split(' ').count(), 2, "{coords}");
        assert_eq!(svg.matches("<circle").count(), 5);
        assert_eq!(svg.matches("<text").count(), svg.matches("</text>").count());
        assert!(svg.contains("no data"));
    }
}
