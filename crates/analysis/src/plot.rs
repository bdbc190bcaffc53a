//! Plots: MDS scatter plots and overlaid histograms, as PNG or SVG (chosen by the file
//! extension), drawn with plotters.
//!
//! Text uses the bundled DejaVu Sans (`assets/DejaVuSans.ttf`, Bitstream Vera / DejaVu licence in
//! `assets/DejaVuSans-LICENSE.txt`), registered once as the family `sans-serif`; no system fonts
//! are needed. SVG files reference the family `sans-serif` in `<text>` elements.
//!
//! Layout: the legend sits in its own panel right of the plot, so it never covers data.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::{register_font, FontStyle};
use shapespace_geometry::io::replace_atomically;

use crate::distortion::{DistortionReport, MapDistortion};
use crate::error::AnalysisError;
use crate::mds::Mds;

const FONT: &str = "sans-serif";
const WIDTH: u32 = 1100;
const HEIGHT: u32 = 760;
const LEGEND_WIDTH: u32 = 260;

static FONT_REGISTERED: OnceLock<bool> = OnceLock::new();

/// Registers the bundled DejaVu Sans as `sans-serif` (once per process).
fn ensure_font() -> Result<(), AnalysisError> {
    let ok = *FONT_REGISTERED
        .get_or_init(|| register_font(FONT, FontStyle::Normal, include_bytes!("../assets/DejaVuSans.ttf")).is_ok());
    if ok {
        Ok(())
    } else {
        Err(AnalysisError::PlotInput {
            message: "the bundled DejaVu Sans font could not be loaded".into(),
        })
    }
}

/// Marker shapes, cycled in this order for the values of the marker column.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Marker {
    Circle,
    Triangle,
    Square,
    Cross,
    Diamond,
    TriangleDown,
    Plus,
    Star,
}

/// The marker cycle: circle, triangle, square, cross, diamond, inverted triangle, plus, star.
pub const MARKERS: [Marker; 8] = [
    Marker::Circle,
    Marker::Triangle,
    Marker::Square,
    Marker::Cross,
    Marker::Diamond,
    Marker::TriangleDown,
    Marker::Plus,
    Marker::Star,
];

/// Tableau 20 (tab10 colours first, then their light variants).
const TAB20: [(u8, u8, u8); 20] = [
    (31, 119, 180),
    (255, 127, 14),
    (44, 160, 44),
    (214, 39, 40),
    (148, 103, 189),
    (140, 86, 75),
    (227, 119, 194),
    (127, 127, 127),
    (188, 189, 34),
    (23, 190, 207),
    (174, 199, 232),
    (255, 187, 120),
    (152, 223, 138),
    (255, 152, 150),
    (197, 176, 213),
    (196, 156, 148),
    (247, 182, 210),
    (199, 199, 199),
    (219, 219, 141),
    (158, 218, 229),
];

/// Colour `k` of `count` categorical colours: Tableau 20 up to 20 values, golden-ratio hue
/// steps with three lightness levels beyond.
pub fn category_color(k: usize, count: usize) -> RGBColor {
    if count <= TAB20.len() {
        let (r, g, b) = TAB20[k % TAB20.len()];
        RGBColor(r, g, b)
    } else {
        // Golden-ratio hue steps keep consecutive categories far apart on the colour wheel.
        let hue = (k as f64 * 0.618_033_988_749_895).fract();
        let lightness = [0.45, 0.62, 0.33][k % 3];
        let (r, g, b) = HSLColor(hue, 0.7, lightness).rgb();
        RGBColor(r, g, b)
    }
}

fn plot_err(path: &Path, e: impl std::fmt::Display) -> AnalysisError {
    AnalysisError::Plot {
        path: path.to_path_buf(),
        message: e.to_string(),
    }
}

/// Distinct values in first-appearance order, and the index of each entry's value. An empty
/// label (unknown, module `stats`) shows as `(no label)` in the legend.
fn categories(values: &[&str]) -> (Vec<String>, Vec<usize>) {
    let mut distinct: Vec<String> = Vec::new();
    let index = values
        .iter()
        .map(|&v| if v.is_empty() { "(no label)" } else { v })
        .map(|v| match distinct.iter().position(|d| d == v) {
            Some(k) => k,
            None => {
                distinct.push(v.to_string());
                distinct.len() - 1
            }
        })
        .collect();
    (distinct, index)
}

type DrawResult<DB> = Result<(), DrawingAreaErrorKind<<DB as DrawingBackend>::ErrorType>>;

/// Draws one marker centred at pixel `c` with half-size `r`.
fn draw_marker<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    c: (i32, i32),
    r: i32,
    marker: Marker,
    color: RGBColor,
) -> DrawResult<DB> {
    let fill = color.mix(0.85).filled();
    let edge = BLACK.mix(0.7).stroke_width(1);
    let stroke = color.stroke_width(3);
    let (x, y) = c;
    let polygon = |pts: Vec<(i32, i32)>| -> DrawResult<DB> {
        area.draw(&Polygon::new(pts.clone(), fill))?;
        let mut closed = pts;
        closed.push(closed[0]);
        area.draw(&PathElement::new(closed, edge))
    };
    match marker {
        Marker::Circle => {
            area.draw(&Circle::new(c, r, fill))?;
            area.draw(&Circle::new(c, r, edge))
        }
        Marker::Square => {
            let s = (r as f64 * 0.9) as i32;
            polygon(vec![(x - s, y - s), (x + s, y - s), (x + s, y + s), (x - s, y + s)])
        }
        Marker::Triangle => {
            let h = (r as f64 * 1.15) as i32;
            polygon(vec![(x, y - h), (x + h, y + h * 3 / 4), (x - h, y + h * 3 / 4)])
        }
        Marker::TriangleDown => {
            let h = (r as f64 * 1.15) as i32;
            polygon(vec![(x, y + h), (x + h, y - h * 3 / 4), (x - h, y - h * 3 / 4)])
        }
        Marker::Diamond => {
            let h = (r as f64 * 1.3) as i32;
            polygon(vec![(x, y - h), (x + h, y), (x, y + h), (x - h, y)])
        }
        Marker::Star => {
            let outer = r as f64 * 1.4;
            let inner = outer * 0.45;
            let pts = (0..10)
                .map(|k| {
                    let rad = if k % 2 == 0 { outer } else { inner };
                    let a = std::f64::consts::PI * (k as f64 / 5.0 - 0.5);
                    (x + (rad * a.cos()).round() as i32, y + (rad * a.sin()).round() as i32)
                })
                .collect();
            polygon(pts)
        }
        Marker::Cross => {
            let s = r;
            area.draw(&PathElement::new(vec![(x - s, y - s), (x + s, y + s)], stroke))?;
            area.draw(&PathElement::new(vec![(x - s, y + s), (x + s, y - s)], stroke))
        }
        Marker::Plus => {
            let s = (r as f64 * 1.2) as i32;
            area.draw(&PathElement::new(vec![(x - s, y), (x + s, y)], stroke))?;
            area.draw(&PathElement::new(vec![(x, y - s), (x, y + s)], stroke))
        }
    }
}

/// One legend entry: a symbol and its text.
enum LegendSymbol {
    Marker(Marker, RGBColor),
    Line(RGBColor),
    None,
}

/// Smallest legend row height before entries are cut off.
const MIN_LEGEND_ROW: i32 = 12;

/// Greedy word wrap of `text` into lines no wider than `max_width` pixels (a single long word
/// stays on its own line).
fn wrap_text<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    text: &str,
    style: &TextStyle,
    max_width: u32,
) -> Result<Vec<String>, DrawingAreaErrorKind<DB::ErrorType>> {
    let mut lines: Vec<String> = Vec::new();
    let mut current = String::new();
    for word in text.split_whitespace() {
        let candidate = if current.is_empty() {
            word.to_string()
        } else {
            format!("{current} {word}")
        };
        if current.is_empty() || area.estimate_text_size(&candidate, style)?.0 <= max_width {
            current = candidate;
        } else {
            lines.push(std::mem::replace(&mut current, word.to_string()));
        }
    }
    if !current.is_empty() || lines.is_empty() {
        lines.push(current);
    }
    Ok(lines)
}

/// Draws the legend panel: sections of (heading, entries); long labels wrap, and rows shrink to
/// fit the panel height.
fn draw_legend<DB: DrawingBackend>(
    panel: &DrawingArea<DB, Shift>,
    sections: &[(String, Vec<(LegendSymbol, String)>)],
) -> DrawResult<DB> {
    let (w, h) = panel.dim_in_pixel();
    let text_x = 54i32;
    let max_font = 17.0;
    let wrap_style = TextStyle::from((FONT, max_font).into_font());
    // Too many entries for the panel even at the smallest row height: keep the first `cap` of
    // every section and end it with "… and N more".
    let top = 80i32;
    let max_rows = ((h as i32 - top - 20) / MIN_LEGEND_ROW).max(1) as usize;
    let full_rows = |cap: usize| -> usize { sections.iter().map(|(_, e)| e.len().min(cap + 1) + 2).sum() };
    let mut cap = sections.iter().map(|(_, e)| e.len()).max().unwrap_or(0);
    while cap > 1 && full_rows(cap) > max_rows {
        cap -= 1;
    }
    let capped: Vec<(String, Vec<(&LegendSymbol, String)>)> = sections
        .iter()
        .map(|(title, entries)| {
            let mut kept: Vec<(&LegendSymbol, String)> =
                entries.iter().take(cap).map(|(s, l)| (s, l.clone())).collect();
            if entries.len() > cap {
                kept.push((&LegendSymbol::None, format!("… and {} more", entries.len() - cap)));
            }
            (title.clone(), kept)
        })
        .collect();
    let sections = &capped;
    let mut wrapped = Vec::with_capacity(sections.len());
    let mut rows = 0usize;
    for (title, entries) in sections {
        let mut lines = Vec::with_capacity(entries.len());
        for (_, label) in entries {
            let l = wrap_text(panel, label, &wrap_style, w.saturating_sub(text_x as u32 + 10))?;
            rows += l.len();
            lines.push(l);
        }
        rows += 2;
        wrapped.push((title, lines));
    }
    if rows == 0 {
        return Ok(());
    }
    let row_h = ((h as i32 - top - 20) / rows as i32).clamp(MIN_LEGEND_ROW, 28);
    let font_size = (row_h as f64 * 0.68).clamp(9.0, max_font);
    let heading = (FONT, font_size + 1.0).into_font().color(&BLACK);
    let text = (FONT, font_size).into_font().color(&BLACK.mix(0.85));
    let mut y = top;
    for ((title, lines), (_, entries)) in wrapped.iter().zip(sections) {
        panel.draw(&Text::new(title.to_string(), (12, y - row_h / 2), heading.clone()))?;
        y += row_h;
        for (label_lines, (symbol, _)) in lines.iter().zip(entries) {
            let cy = y;
            match symbol {
                LegendSymbol::Marker(m, c) => draw_marker(panel, (30, cy), (row_h / 3).clamp(4, 7), *m, *c)?,
                LegendSymbol::Line(c) => {
                    panel.draw(&Rectangle::new([(16, cy - 6), (44, cy + 6)], c.mix(0.3).filled()))?;
                    panel.draw(&PathElement::new(vec![(16, cy), (44, cy)], c.stroke_width(3)))?;
                }
                LegendSymbol::None => {}
            }
            for line in label_lines {
                panel.draw(&Text::new(
                    line.clone(),
                    (text_x, y - (font_size * 0.55) as i32),
                    text.clone(),
                ))?;
                y += row_h;
            }
        }
        y += row_h;
    }
    Ok(())
}

/// Expands `lo..hi` by `pad` of its length (or by 1 if it is empty).
fn padded(lo: f64, hi: f64, pad: f64) -> (f64, f64) {
    let span = hi - lo;
    if span > 0.0 {
        (lo - pad * span, hi + pad * span)
    } else {
        let s = if lo.abs() > 0.0 { 0.1 * lo.abs() } else { 1.0 };
        (lo - s, hi + s)
    }
}

/// How the colour column's values become colours.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ColorScale {
    /// Continuous when every value is a number and there are at least
    /// [`MIN_CONTINUOUS_VALUES`] distinct ones, else categorical.
    #[default]
    Auto,
    /// One colour per distinct value.
    Categorical,
    /// A continuous scale (viridis) from the smallest to the largest value; every non-empty
    /// value must be a number.
    Continuous,
}

/// Distinct numbers a column needs before [`ColorScale::Auto`] colours it continuously (fewer
/// are usually codes of groups: 0/1, 1/2/3).
pub const MIN_CONTINUOUS_VALUES: usize = 6;

/// The labels of an MDS scatter plot (each list has one entry per shape, in the matrix order).
#[derive(Clone, Copy, Debug, Default)]
pub struct ScatterLabels<'a> {
    /// `(column name, values)`: point colours, by [`ColorScale`].
    pub color: Option<(&'a str, &'a [&'a str])>,
    /// `(column name, values)`: one marker shape per distinct value, cycling through [`MARKERS`].
    pub marker: Option<(&'a str, &'a [&'a str])>,
    /// Text written beside each point (the shape names, say).
    pub point_labels: Option<&'a [&'a str]>,
    /// How the colour column becomes colours.
    pub color_scale: ColorScale,
}

/// Viridis, sampled at 0, ¼, ½, ¾ and 1 and interpolated linearly.
const VIRIDIS: [(f64, f64, f64); 5] = [
    (68.0, 1.0, 84.0),
    (59.0, 82.0, 139.0),
    (33.0, 145.0, 140.0),
    (94.0, 201.0, 98.0),
    (253.0, 231.0, 37.0),
];

/// The continuous scale's colour at `t` ∈ [0, 1] (clamped).
pub fn continuous_color(t: f64) -> RGBColor {
    let x = if t.is_finite() { t.clamp(0.0, 1.0) * 4.0 } else { 0.0 };
    let k = (x.floor() as usize).min(3);
    let f = x - k as f64;
    let (a, b) = (VIRIDIS[k], VIRIDIS[k + 1]);
    let mix = |u: f64, v: f64| (u + f * (v - u)).round() as u8;
    RGBColor(mix(a.0, b.0), mix(a.1, b.1), mix(a.2, b.2))
}

/// Grey for points without a value on a continuous scale.
const NO_VALUE: RGBColor = RGBColor(170, 170, 170);

/// Colours of the points.
enum Coloring<'a> {
    None,
    Categorical {
        column: &'a str,
        values: Vec<String>,
        index: Vec<usize>,
    },
    Continuous {
        column: &'a str,
        values: Vec<Option<f64>>,
        lo: f64,
        hi: f64,
    },
}

impl<'a> Coloring<'a> {
    fn new(color: Option<(&'a str, &'a [&'a str])>, scale: ColorScale) -> Result<Self, AnalysisError> {
        let Some((column, raw)) = color else {
            return Ok(Coloring::None);
        };
        let parsed: Vec<Option<f64>> = raw
            .iter()
            .map(|v| v.trim().parse::<f64>().ok().filter(|x| x.is_finite()))
            .collect();
        let numeric = raw.iter().zip(&parsed).all(|(v, p)| v.trim().is_empty() || p.is_some());
        let mut distinct: Vec<f64> = parsed.iter().flatten().copied().collect();
        distinct.sort_by(f64::total_cmp);
        distinct.dedup();
        let continuous = match scale {
            ColorScale::Categorical => false,
            ColorScale::Auto => numeric && distinct.len() >= MIN_CONTINUOUS_VALUES,
            ColorScale::Continuous => {
                if let Some((i, v)) = raw
                    .iter()
                    .zip(&parsed)
                    .enumerate()
                    .find(|(_, (v, p))| !v.trim().is_empty() && p.is_none())
                    .map(|(i, (v, _))| (i, v))
                {
                    return Err(AnalysisError::PlotInput {
                        message: format!(
                            "colour column {column:?} on a continuous scale: value {v:?} of point {i} is not a finite number"
                        ),
                    });
                }
                true
            }
        };
        if continuous {
            let (lo, hi) = (
                distinct.first().copied().unwrap_or(0.0),
                distinct.last().copied().unwrap_or(0.0),
            );
            Ok(Coloring::Continuous {
                column,
                values: parsed,
                lo,
                hi,
            })
        } else {
            let (values, index) = categories(raw);
            Ok(Coloring::Categorical { column, values, index })
        }
    }

    fn color(&self, i: usize) -> RGBColor {
        match self {
            Coloring::None => category_color(0, 1),
            Coloring::Categorical { values, index, .. } => category_color(index[i], values.len()),
            Coloring::Continuous { values, lo, hi, .. } => match values[i] {
                Some(v) if hi > lo => continuous_color((v - lo) / (hi - lo)),
                Some(_) => continuous_color(0.5),
                None => NO_VALUE,
            },
        }
    }

    /// The legend section: every category, or five values along the continuous scale.
    fn legend(&self) -> Option<(String, Vec<(LegendSymbol, String)>)> {
        match self {
            Coloring::None => None,
            Coloring::Categorical { column, values, .. } => Some((
                format!("{column} (colour)"),
                values
                    .iter()
                    .enumerate()
                    .map(|(k, v)| {
                        (
                            LegendSymbol::Marker(Marker::Circle, category_color(k, values.len())),
                            v.clone(),
                        )
                    })
                    .collect(),
            )),
            Coloring::Continuous { column, values, lo, hi } => {
                let steps = if hi > lo { 4 } else { 0 };
                let mut entries: Vec<(LegendSymbol, String)> = (0..=steps)
                    .rev()
                    .map(|k| {
                        let t = if steps == 0 { 0.5 } else { k as f64 / steps as f64 };
                        let v = if steps == 0 { *lo } else { lo + t * (hi - lo) };
                        (
                            LegendSymbol::Marker(Marker::Circle, continuous_color(t)),
                            format_value(v),
                        )
                    })
                    .collect();
                if values.iter().any(Option::is_none) {
                    entries.push((LegendSymbol::Marker(Marker::Circle, NO_VALUE), "(no value)".into()));
                }
                Some((format!("{column} (colour scale)"), entries))
            }
        }
    }
}

/// A legend number: four significant digits, in exponent form outside [1e-3, 1e5).
fn format_value(v: f64) -> String {
    let a = v.abs();
    if v == 0.0 {
        "0".into()
    } else if (1e-3..1e5).contains(&a) {
        let decimals = (3 - a.log10().floor() as i32).max(0) as usize;
        let s = format!("{v:.decimals$}");
        if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            s
        }
    } else {
        format!("{v:.3e}")
    }
}

/// A marker column: its name, its distinct values, and each point's value index.
type MarkerCategories<'a> = (&'a str, Vec<String>, Vec<usize>);

struct ScatterInput<'a> {
    points: Vec<(f64, f64)>,
    x_desc: String,
    y_desc: String,
    color: Coloring<'a>,
    marker: Option<MarkerCategories<'a>>,
    point_labels: Option<&'a [&'a str]>,
    title: &'a str,
}

impl ScatterInput<'_> {
    fn has_legend(&self) -> bool {
        !matches!(self.color, Coloring::None) || self.marker.is_some()
    }

    fn marker(&self, i: usize) -> Marker {
        self.marker
            .as_ref()
            .map_or(Marker::Circle, |m| MARKERS[m.2[i] % MARKERS.len()])
    }

    fn legend_sections(&self) -> Vec<(String, Vec<(LegendSymbol, String)>)> {
        let mut sections = Vec::new();
        sections.extend(self.color.legend());
        if let Some((col, values, _)) = &self.marker {
            let grey = RGBColor(90, 90, 90);
            let entries = values
                .iter()
                .enumerate()
                .map(|(k, v)| (LegendSymbol::Marker(MARKERS[k % MARKERS.len()], grey), v.clone()))
                .collect();
            sections.push((format!("{col} (marker)"), entries));
        }
        sections
    }
}

/// Marker half-size by the number of points (smaller markers for crowded plots).
fn marker_radius(n: usize) -> i32 {
    match n {
        0..=120 => 7,
        121..=300 => 5,
        _ => 4,
    }
}

fn draw_scatter<DB: DrawingBackend>(root: DrawingArea<DB, Shift>, input: &ScatterInput) -> DrawResult<DB> {
    root.fill(&WHITE)?;
    let has_legend = input.has_legend();
    let (w, _) = root.dim_in_pixel();
    let (plot_area, legend_area) = root.split_horizontally(if has_legend { w - LEGEND_WIDTH } else { w });
    let titled = plot_area
        .margin(14, 0, 0, 0)
        .titled(input.title, (FONT, 26).into_font())?;
    let (margin, x_label, y_label) = (20u32, 60u32, 80u32);
    let (tw, th) = titled.dim_in_pixel();
    let plot_w = tw.saturating_sub(2 * margin + y_label).max(1) as f64;
    let plot_h = th.saturating_sub(2 * margin + x_label).max(1) as f64;

    // Equal scale on both axes (MDS coordinates share one unit).
    let (mut x0, mut x1) = input
        .points
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| (a.min(p.0), b.max(p.0)));
    let (mut y0, mut y1) = input
        .points
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| (a.min(p.1), b.max(p.1)));
    (x0, x1) = padded(x0, x1, 0.06);
    (y0, y1) = padded(y0, y1, 0.06);
    let scale = ((x1 - x0) / plot_w).max((y1 - y0) / plot_h);
    let (cx, cy) = (0.5 * (x0 + x1), 0.5 * (y0 + y1));
    let (x0, x1) = (cx - 0.5 * scale * plot_w, cx + 0.5 * scale * plot_w);
    let (y0, y1) = (cy - 0.5 * scale * plot_h, cy + 0.5 * scale * plot_h);

    let mut chart = ChartBuilder::on(&titled)
        .margin(margin)
        .x_label_area_size(x_label)
        .y_label_area_size(y_label)
        .build_cartesian_2d(x0..x1, y0..y1)?;
    chart
        .configure_mesh()
        .x_desc(input.x_desc.as_str())
        .y_desc(input.y_desc.as_str())
        .label_style((FONT, 16))
        .axis_desc_style((FONT, 19))
        .light_line_style(BLACK.mix(0.04))
        .bold_line_style(BLACK.mix(0.12))
        .x_labels(8)
        .y_labels(8)
        .draw()?;
    let radius = marker_radius(input.points.len());
    let label_style = (FONT, 12).into_font().color(&BLACK.mix(0.8));
    for (i, p) in input.points.iter().enumerate() {
        let pixel = chart.backend_coord(p);
        draw_marker(&root, pixel, radius, input.marker(i), input.color.color(i))?;
        if let Some(labels) = input.point_labels {
            root.draw(&Text::new(
                labels[i].to_string(),
                (pixel.0 + radius + 3, pixel.1 - radius - 3),
                label_style.clone(),
            ))?;
        }
    }
    if has_legend {
        draw_legend(&legend_area, &input.legend_sections())?;
    }
    root.present()
}

fn backend_kind(path: &Path) -> Result<&'static str, AnalysisError> {
    match path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .as_deref()
    {
        Some("png") => Ok("png"),
        Some("svg") => Ok("svg"),
        _ => Err(AnalysisError::PlotInput {
            message: format!("{}: plot file must end in .png or .svg", path.display()),
        }),
    }
}

/// Writes a plot drawn by `$draw` (a function of a drawing area) to `$path` as PNG or SVG, by
/// the extension, atomically.
macro_rules! render {
    ($path:expr, $size:expr, $draw:expr) => {{
        let path: &Path = $path;
        match backend_kind(path)? {
            "png" => replace_atomically(
                path,
                |temp| $draw(BitMapBackend::new(temp, $size).into_drawing_area()).map_err(|e| plot_err(path, e)),
                |e| AnalysisError::io(path, e),
            ),
            _ => replace_atomically(
                path,
                |temp| $draw(SVGBackend::new(temp, $size).into_drawing_area()).map_err(|e| plot_err(path, e)),
                |e| AnalysisError::io(path, e),
            ),
        }
    }};
}

/// Checks the label lists against `n` points, the extension, and loads the font; returns the
/// colouring and the marker categories.
fn scatter_labels<'a>(
    path: &Path,
    n: usize,
    labels: &ScatterLabels<'a>,
) -> Result<(Coloring<'a>, Option<MarkerCategories<'a>>), AnalysisError> {
    if n == 0 {
        return Err(AnalysisError::PlotInput {
            message: "no points to plot".into(),
        });
    }
    let point_labels = labels.point_labels.map(|v| ("point labels", v));
    for (what, given) in [
        ("colour column", labels.color),
        ("marker column", labels.marker),
        ("labels", point_labels),
    ] {
        if let Some((col, values)) = given {
            if values.len() != n {
                return Err(AnalysisError::PlotInput {
                    message: format!("{what} {col:?} has {} values for {n} points", values.len()),
                });
            }
        }
    }
    backend_kind(path)?;
    ensure_font()?;
    let coloring = Coloring::new(labels.color, labels.color_scale)?;
    let marker = labels.marker.map(|(col, v)| {
        let (d, i) = categories(v);
        (col, d, i)
    });
    Ok((coloring, marker))
}

/// "MDS k (xx.x% var)" for axis `k` (from 0).
fn axis_name(mds: &Mds, k: usize) -> String {
    let share = mds
        .variance_shares
        .get(k)
        .map_or(String::new(), |s| format!(" ({:.1}% var)", 100.0 * s));
    format!("MDS {}{share}", k + 1)
}

/// Scatter plot of the first two MDS coordinates (one coordinate against 0 if `dims == 1`),
/// written as PNG or SVG according to the extension of `path` (1100×760 px).
///
/// - `labels.color`: `(column name, one value per shape)`: one colour per distinct value
///   (Tableau 20, evenly spaced hues beyond 20 values, in first-appearance order), or a
///   continuous viridis scale for numbers ([`ColorScale`]; points without a value grey).
/// - `labels.marker`: likewise, one marker shape per value, cycling through [`MARKERS`].
/// - `labels.point_labels`: text beside each point.
/// - Axes read "MDS 1 (xx.x% var)" with the shares of [`Mds::variance_shares`]; both axes use the
///   same scale. The legend is in a panel right of the plot.
///
/// Errors: label lengths differing from `#shapes`, a non-number on a continuous scale, an
/// unknown extension, drawing or write failures ([`AnalysisError::Plot`] with the path).
pub fn mds_scatter(path: &Path, mds: &Mds, labels: &ScatterLabels, title: &str) -> Result<(), AnalysisError> {
    let (color, marker) = scatter_labels(path, mds.coordinates.len(), labels)?;
    let points: Vec<(f64, f64)> = mds
        .coordinates
        .iter()
        .map(|c| (c[0], c.get(1).copied().unwrap_or(0.0)))
        .collect();
    let input = ScatterInput {
        points,
        x_desc: axis_name(mds, 0),
        y_desc: if mds.dims() > 1 {
            axis_name(mds, 1)
        } else {
            String::from("(1-D embedding)")
        },
        color,
        marker,
        point_labels: labels.point_labels,
        title,
    };
    render!(path, (WIDTH, HEIGHT), |area| draw_scatter(area, &input))
}

/// The most axes [`mds_scatter_matrix`] draws.
pub const MAX_MATRIX_AXES: usize = 8;

/// Scatter matrix of the first `k` MDS axes (2 ≤ k ≤ `mds.dims()`, at most
/// [`MAX_MATRIX_AXES`]): panel (i, j) plots axis j+1 (horizontal) against axis i+1, the diagonal
/// names the axes with their variance shares; colours, markers and the legend as in
/// [`mds_scatter`] (point labels are left out: the panels are small). PNG or SVG by the
/// extension of `path`, 1100×(260 + 110·k) px.
pub fn mds_scatter_matrix(
    path: &Path,
    mds: &Mds,
    k: usize,
    labels: &ScatterLabels,
    title: &str,
) -> Result<(), AnalysisError> {
    if !(2..=MAX_MATRIX_AXES.min(mds.dims())).contains(&k) {
        return Err(AnalysisError::PlotInput {
            message: format!(
                "a scatter matrix of {k} axes needs 2 to {} axes of an embedding with {}",
                MAX_MATRIX_AXES.min(mds.dims()).max(2),
                mds.dims()
            ),
        });
    }
    let (color, marker) = scatter_labels(path, mds.coordinates.len(), labels)?;
    let input = ScatterInput {
        points: Vec::new(),
        x_desc: String::new(),
        y_desc: String::new(),
        color,
        marker,
        point_labels: None,
        title,
    };
    let size = (WIDTH, 260 + 110 * k as u32);
    render!(path, size, |area| draw_scatter_matrix(area, mds, k, &input))
}

fn draw_scatter_matrix<DB: DrawingBackend>(
    root: DrawingArea<DB, Shift>,
    mds: &Mds,
    k: usize,
    input: &ScatterInput,
) -> DrawResult<DB> {
    root.fill(&WHITE)?;
    let (w, _) = root.dim_in_pixel();
    let has_legend = input.has_legend();
    let (plot_area, legend_area) = root.split_horizontally(if has_legend { w - LEGEND_WIDTH } else { w });
    let titled = plot_area
        .margin(14, 10, 10, 10)
        .titled(input.title, (FONT, 24).into_font())?;
    let ranges: Vec<(f64, f64)> = (0..k)
        .map(|a| {
            let (lo, hi) = mds
                .coordinates
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), c| {
                    (lo.min(c[a]), hi.max(c[a]))
                });
            padded(lo, hi, 0.08)
        })
        .collect();
    let n = mds.coordinates.len();
    let radius = (marker_radius(n) - 2).max(2);
    let cells = titled.split_evenly((k, k));
    for (cell_index, cell) in cells.iter().enumerate() {
        let (i, j) = (cell_index / k, cell_index % k);
        if i == j {
            let (cw, ch) = cell.dim_in_pixel();
            let style = (FONT, 15).into_font().color(&BLACK);
            let name = axis_name(mds, i);
            let (tw, th) = cell.estimate_text_size(&name, &style)?;
            cell.draw(&Text::new(
                name,
                ((cw as i32 - tw as i32) / 2, (ch as i32 - th as i32) / 2),
                style,
            ))?;
            continue;
        }
        let mut chart = ChartBuilder::on(cell)
            .margin(3)
            .x_label_area_size(if i + 1 == k { 18 } else { 0 })
            .y_label_area_size(if j == 0 { 34 } else { 0 })
            .build_cartesian_2d(ranges[j].0..ranges[j].1, ranges[i].0..ranges[i].1)?;
        chart
            .configure_mesh()
            .disable_mesh()
            .x_labels(3)
            .y_labels(3)
            .label_style((FONT, 10))
            .draw()?;
        let plotting = chart.plotting_area().clone();
        for (p, c) in mds.coordinates.iter().enumerate() {
            let pixel = chart.backend_coord(&(c[j], c[i]));
            draw_marker(&root, pixel, radius, input.marker(p), input.color.color(p))?;
        }
        let (x_px, y_px) = plotting.get_pixel_range();
        let frame = [(x_px.start, y_px.start), (x_px.end - 1, y_px.end - 1)];
        root.draw(&Rectangle::new(frame, BLACK.mix(0.25)))?;
    }
    if has_legend {
        draw_legend(&legend_area, &input.legend_sections())?;
    }
    root.present()
}

/// Per-series bin counts of a histogram.
#[derive(Clone, Debug, PartialEq)]
pub struct HistogramCounts {
    /// Bin range `lo..hi` (bins are `[lo + k·w, lo + (k+1)·w)`, the last one closed).
    pub range: (f64, f64),
    /// `counts[s][k]`: values of series `s` in bin `k`.
    pub counts: Vec<Vec<usize>>,
    /// Values of each series outside the range or not finite (not drawn).
    pub outside: Vec<usize>,
}

/// Bins every series into `bins` equal bins over `range`, or over the min..max of all finite
/// values when `range` is `None`.
pub fn histogram_counts(
    series: &[(&str, &[f64])],
    bins: usize,
    range: Option<(f64, f64)>,
) -> Result<HistogramCounts, AnalysisError> {
    if bins == 0 {
        return Err(AnalysisError::PlotInput {
            message: "histogram needs at least one bin".into(),
        });
    }
    let (lo, hi) = match range {
        Some((lo, hi)) if lo.is_finite() && hi.is_finite() && lo < hi => (lo, hi),
        Some((lo, hi)) => {
            return Err(AnalysisError::PlotInput {
                message: format!("histogram range {lo}..{hi} must be finite and increasing"),
            })
        }
        None => {
            let finite = series
                .iter()
                .flat_map(|(_, v)| v.iter().copied())
                .filter(|v| v.is_finite());
            let (lo, hi) = finite.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(v), b.max(v)));
            if !lo.is_finite() {
                return Err(AnalysisError::PlotInput {
                    message: "histogram series contain no finite values".into(),
                });
            }
            if lo < hi {
                (lo, hi)
            } else {
                padded(lo, hi, 0.0)
            }
        }
    };
    let width = (hi - lo) / bins as f64;
    let mut counts = vec![vec![0usize; bins]; series.len()];
    let mut outside = vec![0usize; series.len()];
    for (s, (_, values)) in series.iter().enumerate() {
        for &v in values.iter() {
            if !(v >= lo && v <= hi) {
                outside[s] += 1;
                continue;
            }
            let k = (((v - lo) / width) as usize).min(bins - 1);
            counts[s][k] += 1;
        }
    }
    Ok(HistogramCounts {
        range: (lo, hi),
        counts,
        outside,
    })
}

struct HistogramInput<'a> {
    names: Vec<&'a str>,
    hist: HistogramCounts,
    fractions: Vec<Vec<f64>>,
    title: &'a str,
    x_label: &'a str,
}

fn draw_histograms<DB: DrawingBackend>(root: DrawingArea<DB, Shift>, input: &HistogramInput) -> DrawResult<DB> {
    root.fill(&WHITE)?;
    let (w, _) = root.dim_in_pixel();
    let (plot_area, legend_area) = root.split_horizontally(w - LEGEND_WIDTH);
    let titled = plot_area
        .margin(14, 0, 0, 0)
        .titled(input.title, (FONT, 26).into_font())?;
    let (lo, hi) = input.hist.range;
    let bins = input.fractions.first().map_or(1, Vec::len);
    let width = (hi - lo) / bins as f64;
    let y_max = input.fractions.iter().flatten().copied().fold(0.0f64, f64::max);
    let y_top = if y_max > 0.0 { 1.08 * y_max } else { 1.0 };
    let mut chart = ChartBuilder::on(&titled)
        .margin(20)
        .x_label_area_size(60)
        .y_label_area_size(90)
        .build_cartesian_2d(lo..hi, 0.0..y_top)?;
    chart
        .configure_mesh()
        .x_desc(input.x_label)
        .y_desc("fraction of values per bin")
        .label_style((FONT, 16))
        .axis_desc_style((FONT, 19))
        .light_line_style(BLACK.mix(0.04))
        .bold_line_style(BLACK.mix(0.12))
        .x_labels(10)
        .y_labels(8)
        .draw()?;
    let count = input.fractions.len();
    for (s, fr) in input.fractions.iter().enumerate() {
        let color = category_color(s, count.max(10));
        chart.draw_series(fr.iter().enumerate().map(|(k, &f)| {
            let x = lo + k as f64 * width;
            Rectangle::new([(x, 0.0), (x + width, f)], color.mix(0.22).filled())
        }))?;
    }
    for (s, fr) in input.fractions.iter().enumerate() {
        let color = category_color(s, count.max(10));
        let mut steps = Vec::with_capacity(2 * bins + 2);
        steps.push((lo, 0.0));
        for (k, &f) in fr.iter().enumerate() {
            let x = lo + k as f64 * width;
            steps.push((x, f));
            steps.push((x + width, f));
        }
        steps.push((hi, 0.0));
        chart.draw_series(std::iter::once(PathElement::new(steps, color.stroke_width(3))))?;
    }
    let entries = input
        .names
        .iter()
        .enumerate()
        .map(|(s, name)| {
            let total: usize = input.hist.counts[s].iter().sum();
            (
                LegendSymbol::Line(category_color(s, count.max(10))),
                format!("{name} (n={total})"),
            )
        })
        .collect();
    draw_legend(&legend_area, &[(String::from("series"), entries)])?;
    root.present()
}

/// Overlaid histograms of several distributions, written as PNG or SVG by the extension of
/// `path` (1100×760 px): per series, semi-transparent bars and a step outline of the fraction
/// of its binned values per bin (so series of different sizes compare), with a legend panel
/// giving each series' name and count. `bins` equal bins over `range` (or the min..max of all
/// finite values). Used for distortion histograms (Su et al. 2015, Figs. 2 and 7).
///
/// Values outside the range and non-finite values are not drawn; their number per series is
/// returned in [`HistogramCounts::outside`].
pub fn histograms(
    path: &Path,
    series: &[(&str, &[f64])],
    bins: usize,
    range: Option<(f64, f64)>,
    title: &str,
    x_label: &str,
) -> Result<HistogramCounts, AnalysisError> {
    if series.is_empty() {
        return Err(AnalysisError::PlotInput {
            message: "no histogram series".into(),
        });
    }
    backend_kind(path)?;
    ensure_font()?;
    let hist = histogram_counts(series, bins, range)?;
    let fractions = hist
        .counts
        .iter()
        .map(|c| {
            let total: usize = c.iter().sum();
            c.iter()
                .map(|&k| if total > 0 { k as f64 / total as f64 } else { 0.0 })
                .collect()
        })
        .collect();
    let input = HistogramInput {
        names: series.iter().map(|(n, _)| *n).collect(),
        hist,
        fractions,
        title,
        x_label,
    };
    render!(path, (WIDTH, HEIGHT), |area| draw_histograms(area, &input))?;
    Ok(input.hist)
}

/// A histogram to write: file stem, title, x label and the values it plots.
type PlotSpec = (&'static str, &'static str, &'static str, fn(&MapDistortion) -> &[f64]);

/// Writes the distortion histograms of every map of `report` into `dir` (created if missing),
/// each as PNG and SVG, as in Su et al. 2015, Fig. 2 (e)–(h): `area_distortion` (Υ per face),
/// `angle_distortion` (degrees per face) and `quasi_conformal_distortion` (Λ per face), all maps
/// overlaid. Returns the written paths. Ranges: min..max of all maps' finite values (Υ and Λ
/// of flipped faces are finite; an infinite Λ of a degenerate face is left out of the plot).
pub fn write_distortion_histograms(
    report: &DistortionReport,
    dir: &Path,
    bins: usize,
) -> Result<Vec<PathBuf>, AnalysisError> {
    std::fs::create_dir_all(dir).map_err(|e| AnalysisError::io(dir, e))?;
    let mut written = Vec::new();
    let plots: [PlotSpec; 3] = [
        (
            "area_distortion",
            "Area distortion",
            "Υ = ln(A_2D / A_3D) per face",
            |m| &m.face_area_distortion,
        ),
        (
            "angle_distortion",
            "Angle distortion",
            "mean |θ_3D − θ_2D| per face (degrees)",
            |m| &m.face_angle_distortion_deg,
        ),
        (
            "quasi_conformal_distortion",
            "Quasi-conformal distortion",
            "Λ = ln(γ_max / γ_min) per face",
            |m| &m.face_quasi_conformal_distortion,
        ),
    ];
    for (stem, title, x_label, get) in plots {
        let series: Vec<(&str, &[f64])> = report.maps.iter().map(|m| (m.name.as_str(), get(m))).collect();
        for ext in ["png", "svg"] {
            let path = dir.join(format!("{stem}.{ext}"));
            histograms(&path, &series, bins, None, title, x_label)?;
            written.push(path);
        }
    }
    Ok(written)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Auto: numbers with at least six distinct values go on the continuous scale, from
    /// viridis' first colour at the smallest to its last at the largest, an empty cell grey;
    /// fewer distinct numbers, or a word among them, stay categorical.
    #[test]
    fn numeric_columns_get_a_continuous_scale() {
        let values = ["3", "1.5", "", "9", "4", "7", "2e0"];
        let c = Coloring::new(Some(("x", &values)), ColorScale::Auto).unwrap();
        let Coloring::Continuous { lo, hi, .. } = c else {
            panic!("not continuous")
        };
        assert_eq!((lo, hi), (1.5, 9.0));
        assert_eq!(c.color(1), RGBColor(68, 1, 84));
        assert_eq!(c.color(3), RGBColor(253, 231, 37));
        assert_eq!(c.color(2), NO_VALUE);
        // 4 lies between 3 and 7: its green channel too (viridis' green rises throughout)
        assert!(c.color(0).1 < c.color(4).1 && c.color(4).1 < c.color(5).1);
        let few = ["1", "2", "1", "2", "3"];
        assert!(matches!(
            Coloring::new(Some(("x", &few)), ColorScale::Auto).unwrap(),
            Coloring::Categorical { .. }
        ));
        let mixed = ["1", "2", "3", "4", "5", "6", "n/a"];
        assert!(matches!(
            Coloring::new(Some(("x", &mixed)), ColorScale::Auto).unwrap(),
            Coloring::Categorical { .. }
        ));
        assert!(Coloring::new(Some(("x", &mixed)), ColorScale::Continuous).is_err());
        assert!(matches!(
            Coloring::new(Some(("x", &few)), ColorScale::Continuous).unwrap(),
            Coloring::Continuous { .. }
        ));
    }

    #[test]
    fn legend_numbers_keep_four_significant_digits() {
        assert_eq!(format_value(20.0), "20");
        assert_eq!(format_value(0.123456), "0.1235");
        assert_eq!(format_value(1234.5678), "1235");
        assert_eq!(format_value(-2.5), "-2.5");
        assert_eq!(format_value(1.5e-7), "1.500e-7");
        assert_eq!(format_value(0.0), "0");
    }

    #[test]
    fn empty_labels_are_one_legend_entry_named_as_unknown() {
        let (names, index) = categories(&["a", "", "b", "", "a"]);
        assert_eq!(names, ["a", "(no label)", "b"]);
        assert_eq!(index, [0, 1, 2, 1, 0]);
    }
}
