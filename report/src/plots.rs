//! SVG charts for the reports, drawn with plotters' SVG backend in `style`'s sizes, fonts and
//! colours (no fonts needed: the browser, or `pdf`, lays out the text). A chart has no title,
//! as the figure's caption names it, and its legend sits under the plot, never over the data.

use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use crate::style::{self, Size, Swatch};

/// A shaded band: its name and (x, low, high) points.
pub type Band = (String, Vec<(f64, f64, f64)>);

/// An arrow on a chart: from, to, and its label at its tail.
pub type Arrow = ((f64, f64), (f64, f64), String);

/// One named line of a chart.
pub struct Series {
    pub name: String,
    pub points: Vec<(f64, f64)>,
}

pub struct Chart<'a> {
    pub x_label: &'a str,
    pub y_label: &'a str,
    pub series: Vec<Series>,
    /// Horizontal reference lines: (y, label).
    pub levels: Vec<(f64, String)>,
    /// Min–max bands drawn under the lines: (name, x, low, high).
    pub bands: Vec<Band>,
    /// Keep x and y at the same scale (maps).
    pub equal_axes: bool,
    /// Labels at points: (x, y, text).
    pub labels: Vec<(f64, f64, String)>,
    /// Marked points: (x, y, name), drawn as circles.
    pub markers: Vec<(f64, f64, String)>,
    /// Named sets of points drawn as small dots, one colour each.
    pub dots: Vec<Series>,
    /// The colour of each set of dots that must mean the same in every chart (a cause of loss),
    /// by the set's index; others take their family's.
    pub dot_colors: Vec<RGBColor>,
    /// Start the y axis at zero (counts and rates, whose small wobbles are not a trend).
    pub y_from_zero: bool,
    /// Fault windows along x (time), shaded; one of no width is a line.
    pub windows: Vec<(f64, f64)>,
    /// Arrows: (from, to, label), e.g. the water current on a map.
    pub arrows: Vec<Arrow>,
    /// Rows named on the y axis (links): category c sits at y = c, and the axis writes the
    /// names alone, never a number between two rows.
    pub y_categories: Vec<String>,
}

/// How many ticks the y axis writes at most: five levels are read at a glance.
const Y_TICKS: usize = 5;

/// A fault window's shade: light, so that the lines over it keep their colour.
const SHADE: f64 = 0.35;

/// A band's shade.
const BAND: f64 = 0.2;

/// A fault of no width: the fault's yellow darkened so that a thin line shows (orange is half
/// duplex's).
const FAULT_LINE: RGBColor = RGBColor(190, 160, 0);

/// Margins around the plot, pt: above it and right of it at least (room for half the top y
/// label, and the last x label), left and under it.
const TOP: f64 = 5.0;
const RIGHT: f64 = 5.0;
const LEFT: f64 = 2.0;
const BOTTOM: f64 = 2.0;

/// An axis, a level, a marker's ring: thinner than the data.
fn thin() -> u32 {
    style::units(0.6).max(1) as u32
}

/// A tick mark's length; plotters puts its label twice as far from the axis.
fn tick() -> i32 {
    style::units(2.5)
}

/// A level's dash and a fault of no width's, in units.
fn level_dash() -> (i32, i32) {
    (style::units(3.0), style::units(2.0))
}

fn fault_dash() -> (i32, i32) {
    (style::units(2.0), style::units(1.5))
}

/// The width of `text` at `pt` points, in units: DejaVu Sans' digits are 0.64 em wide, and
/// most of its letters narrower.
fn text_width(text: &str, pt: f64) -> i32 {
    (text.chars().count() as f64 * 0.64 * pt / 72.0 * style::DPI).ceil() as i32
}

/// The labels plotters writes along `range` for at most `n` ticks.
fn tick_labels(range: (f64, f64), n: usize, format: &dyn Fn(&f64) -> String) -> Vec<String> {
    RangedCoordf64::from(range.0..range.1)
        .key_points(n)
        .iter()
        .map(format)
        .collect()
}

/// Where a figure's parts go, in SVG units: the label areas fit the widest tick label, so that
/// a narrow figure keeps its plot as wide as its labels allow.
struct Layout {
    /// The legend's height, under the plot.
    legend: u32,
    /// How many ticks each axis writes at most.
    x_ticks: usize,
    y_ticks: usize,
    /// Under the plot: tick labels and the axis' description.
    x_area: i32,
    /// Left of the plot: tick labels and the axis' description.
    y_area: i32,
    /// Right of the plot: room for half the last x label.
    right: i32,
}

impl Layout {
    fn new(legend: u32, (x_ticks, y_ticks): (usize, usize), x_labels: &[String], y_labels: &[String]) -> Layout {
        let widest = |labels: &[String]| labels.iter().map(|l| text_width(l, style::TICK_PT)).max().unwrap_or(0);
        let description = style::units(style::LABEL_PT * 1.3);
        Layout {
            legend,
            x_ticks,
            y_ticks,
            x_area: 2 * tick() + style::units(style::TICK_PT * 1.2) + description + style::units(1.0),
            y_area: 2 * tick() + widest(y_labels) + description + style::units(2.0),
            right: (widest(x_labels) / 2 + style::units(1.0)).max(style::units(RIGHT)),
        }
    }

    /// The plot's width and height in a figure of `(w, h)` units.
    fn plot(&self, (w, h): (u32, u32)) -> (f64, f64) {
        let width = w as i32 - style::units(LEFT) - self.y_area - self.right;
        let height = h as i32 - self.legend as i32 - style::units(TOP) - style::units(BOTTOM) - self.x_area;
        (f64::from(width.max(1)), f64::from(height.max(1)))
    }
}

type Area<'a> = DrawingArea<SVGBackend<'a>, plotters::coord::Shift>;

type Plot<'c, 'b> = ChartContext<'c, SVGBackend<'b>, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

/// One axis of a chart: its range, its description and how its ticks are written.
struct Axis<'f> {
    range: (f64, f64),
    desc: &'f str,
    format: &'f dyn Fn(&f64) -> String,
}

/// The chart on `area` (the figure above its legend), its axes, ticks and grid drawn; a grid
/// line at each labelled tick alone, as finer ones blur in print.
fn axes<'c, 'b>(
    area: &Area<'b>,
    layout: &Layout,
    x: Axis,
    y: Axis,
    x_grid: bool,
) -> Result<Plot<'c, 'b>, Box<dyn std::error::Error>> {
    let mut chart = ChartBuilder::on(area)
        .margin_top(style::units(TOP))
        .margin_left(style::units(LEFT))
        .margin_bottom(style::units(BOTTOM))
        .margin_right(layout.right)
        .x_label_area_size(layout.x_area)
        .y_label_area_size(layout.y_area)
        .build_cartesian_2d(x.range.0..x.range.1, y.range.0..y.range.1)?;
    {
        let mut mesh = chart.configure_mesh();
        mesh.x_labels(layout.x_ticks)
            .y_labels(layout.y_ticks)
            .x_label_formatter(x.format)
            .y_label_formatter(y.format)
            .x_desc(x.desc)
            .y_desc(y.desc)
            .label_style(style::font(style::TICK_PT))
            .axis_desc_style(style::font(style::LABEL_PT))
            .axis_style(style::INK.stroke_width(thin()))
            .bold_line_style(style::INK.mix(0.12).stroke_width(1))
            .max_light_lines(0)
            .set_all_tick_mark_size(tick());
        if !x_grid {
            mesh.disable_x_mesh();
        }
        mesh.draw()?;
    }
    Ok(chart)
}

/// `x` and `y` widened about their centres so that a unit is as long on both across a plot of
/// `plot` units.
fn equalise(x: (f64, f64), y: (f64, f64), plot: (f64, f64)) -> ((f64, f64), (f64, f64)) {
    let scale = ((x.1 - x.0) / plot.0).max((y.1 - y.0) / plot.1);
    let (cx, cy) = (0.5 * (x.0 + x.1), 0.5 * (y.0 + y.1));
    (
        (cx - 0.5 * scale * plot.0, cx + 0.5 * scale * plot.0),
        (cy - 0.5 * scale * plot.1, cy + 0.5 * scale * plot.1),
    )
}

impl<'a> Chart<'a> {
    pub fn new(x_label: &'a str, y_label: &'a str) -> Chart<'a> {
        Chart {
            x_label,
            y_label,
            series: Vec::new(),
            levels: Vec::new(),
            bands: Vec::new(),
            equal_axes: false,
            labels: Vec::new(),
            markers: Vec::new(),
            dots: Vec::new(),
            dot_colors: Vec::new(),
            y_from_zero: false,
            windows: Vec::new(),
            arrows: Vec::new(),
            y_categories: Vec::new(),
        }
    }

    /// The chart with `windows` (start, end) shaded: faults on a time axis.
    pub fn with_windows(mut self, windows: &[(f64, f64)]) -> Chart<'a> {
        self.windows = windows.to_vec();
        self
    }

    fn bounds(&self) -> ((f64, f64), (f64, f64)) {
        let xs = self
            .series
            .iter()
            .flat_map(|s| s.points.iter().map(|p| p.0))
            .chain(self.bands.iter().flat_map(|b| b.1.iter().map(|p| p.0)))
            .chain(self.dots.iter().flat_map(|s| s.points.iter().map(|p| p.0)))
            .chain(self.arrows.iter().flat_map(|a| [a.0 .0, a.1 .0]));
        let ys = self
            .series
            .iter()
            .flat_map(|s| s.points.iter().map(|p| p.1))
            .chain(self.y_from_zero.then_some(0.0))
            .chain(self.levels.iter().map(|l| l.0))
            .chain(self.bands.iter().flat_map(|b| b.1.iter().flat_map(|p| [p.1, p.2])))
            .chain(self.markers.iter().map(|m| m.1))
            .chain(self.dots.iter().flat_map(|s| s.points.iter().map(|p| p.1)))
            .chain(self.arrows.iter().flat_map(|a| [a.0 .1, a.1 .1]));
        let range = |it: &mut dyn Iterator<Item = f64>| {
            let (lo, hi) = it
                .filter(|v| v.is_finite())
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(v), b.max(v)));
            if lo > hi {
                (0.0, 1.0)
            } else if hi - lo < 1e-9 {
                (lo - 0.5, hi + 0.5)
            } else {
                let pad = 0.05 * (hi - lo);
                (lo - pad, hi + pad)
            }
        };
        let xs_all: Vec<f64> = xs.chain(self.markers.iter().map(|m| m.0)).collect();
        let y = if self.y_categories.is_empty() {
            range(&mut ys.into_iter())
        } else {
            (-0.5, self.y_categories.len() as f64 - 0.5)
        };
        (range(&mut xs_all.into_iter()), y)
    }

    /// The fault windows that meet `x`, cut to it.
    fn shown(&self, x: (f64, f64)) -> Vec<(f64, f64)> {
        self.windows
            .iter()
            .filter(|w| w.1 >= x.0 && w.0 <= x.1)
            .map(|w| (w.0.max(x.0), w.1.min(x.1)))
            .collect()
    }

    fn dot_color(&self, k: usize) -> RGBColor {
        self.dot_colors.get(k).copied().unwrap_or_else(|| style::family(k))
    }

    /// The legend's entries: lines, dots, bands, levels, then the fault windows `shown`.
    fn entries(&self, shown: &[(f64, f64)]) -> Vec<(String, Swatch)> {
        let mut out: Vec<(String, Swatch)> = Vec::new();
        for (k, s) in self.series.iter().enumerate() {
            // A line of no value at all is not drawn, nor named.
            if s.points.iter().any(|p| p.1.is_finite()) {
                out.push((s.name.clone(), Swatch::family(k, false)));
            }
        }
        for (k, s) in self.dots.iter().enumerate() {
            out.push((
                s.name.clone(),
                Swatch::Dot {
                    colour: self.dot_color(k),
                },
            ));
        }
        for (k, (name, _)) in self.bands.iter().enumerate() {
            out.push((
                name.clone(),
                Swatch::Fill {
                    colour: style::family(k),
                    alpha: BAND,
                },
            ));
        }
        for (_, name) in &self.levels {
            out.push((
                name.clone(),
                Swatch::Line {
                    colour: style::INK,
                    dash: Some(level_dash()),
                    marker: None,
                },
            ));
        }
        let wide = shown.iter().any(|w| w.1 - w.0 > 1e-9);
        if wide {
            out.push((
                "fault window".into(),
                Swatch::Fill {
                    colour: style::FAULT,
                    alpha: SHADE,
                },
            ));
        }
        if shown.iter().any(|w| w.1 - w.0 <= 1e-9) {
            out.push((
                if wide { "fault instant" } else { "fault window" }.into(),
                Swatch::Line {
                    colour: FAULT_LINE,
                    dash: Some(fault_dash()),
                    marker: None,
                },
            ));
        }
        out
    }

    /// Where the parts of a figure of `size` go, its axes spanning `x` and `y`.
    fn layout(&self, size: Size, legend: u32, x: (f64, f64), y: (f64, f64)) -> Layout {
        // Fewer on a narrow figure, where six would run into each other.
        let x_ticks = if size.width < 3.0 { 4 } else { 6 };
        let x_labels = tick_labels(x, x_ticks, &style::ticks(x, x_ticks));
        let y_labels = if self.y_categories.is_empty() {
            tick_labels(y, Y_TICKS, &style::ticks(y, Y_TICKS))
        } else {
            self.y_categories.clone()
        };
        let mut layout = Layout::new(legend, (x_ticks, Y_TICKS), &x_labels, &y_labels);
        if !self.y_categories.is_empty() {
            // Every row named where the names fit, else every second, fifth, tenth… (plotters'
            // steps, whole rows all).
            let fit = layout.plot(size.pixels()).1 / f64::from(style::units(style::TICK_PT * 1.25));
            layout.y_ticks = self.y_categories.len().min((fit as usize).max(1));
        }
        layout
    }

    /// The size of this chart, `plot.width` wide, whose drawing above its legend has `plot`'s
    /// shape: a long legend makes the figure taller rather than the data flatter.
    pub fn fitted(&self, plot: Size) -> Size {
        let (w, h) = plot.pixels();
        let legend = style::legend_height(&self.entries(&self.shown(self.bounds().0)), w);
        Size {
            aspect: f64::from(h + legend) / f64::from(w.max(1)),
            ..plot
        }
    }

    /// The chart as an SVG document of `size` (`size.pixels()` units, printed at its width in
    /// inches).
    pub fn svg(&self, size: Size) -> String {
        let pixels = size.pixels();
        let (data_x, data_y) = self.bounds();
        let shown = self.shown(data_x);
        let entries = self.entries(&shown);
        let legend = style::legend_height(&entries, pixels.0);
        let (mut x, mut y) = (data_x, data_y);
        let mut layout = self.layout(size, legend, x, y);
        if self.equal_axes {
            // Stretch the narrower axis so that a metre is as long on both; its new tick labels
            // may be wider and the plot narrower, hence a second pass.
            for _ in 0..2 {
                (x, y) = equalise(data_x, data_y, layout.plot(pixels));
                layout = self.layout(size, legend, x, y);
            }
        }
        let mut out = String::new();
        {
            let root = SVGBackend::with_string(&mut out, pixels).into_drawing_area();
            let _ = self.draw(&root, &layout, &entries, &shown, (x, y));
            let _ = root.present();
        }
        style::in_inches(out, size)
    }

    fn draw(
        &self,
        root: &Area,
        layout: &Layout,
        entries: &[(String, Swatch)],
        shown: &[(f64, f64)],
        (x, y): ((f64, f64), (f64, f64)),
    ) -> Result<(), Box<dyn std::error::Error>> {
        root.fill(&WHITE)?;
        let (_, h) = root.dim_in_pixel();
        let (upper, under) = root.split_vertically(h.saturating_sub(layout.legend));
        let x_format = style::ticks(x, layout.x_ticks);
        let numbers = style::ticks(y, layout.y_ticks);
        let categories = |v: &f64| category_at(&self.y_categories, *v);
        let y_format: &dyn Fn(&f64) -> String = if self.y_categories.is_empty() {
            &numbers
        } else {
            &categories
        };
        let mut chart = axes(
            &upper,
            layout,
            Axis {
                range: x,
                desc: self.x_label,
                format: &x_format,
            },
            Axis {
                range: y,
                desc: self.y_label,
                format: y_format,
            },
            true,
        )?;
        for &(start, end) in shown {
            let (start, end) = (start.max(x.0), end.min(x.1));
            if end - start > 1e-9 {
                chart.draw_series(std::iter::once(Rectangle::new(
                    [(start, y.0), (end, y.1)],
                    style::FAULT.mix(SHADE).filled(),
                )))?;
            } else {
                let (on, off) = fault_dash();
                chart.draw_series(DashedLineSeries::new(
                    vec![(start, y.0), (start, y.1)],
                    on,
                    off,
                    FAULT_LINE.stroke_width(style::line_width()),
                ))?;
            }
        }
        let note = style::font(style::NOTE_PT);
        for (from, to, label) in &self.arrows {
            let pen = style::INK.stroke_width(style::line_width());
            let (dx, dy) = (to.0 - from.0, to.1 - from.1);
            // The head: two strokes back from the tip at ±25°, a quarter of the shaft long.
            let head = |turn: f64| {
                let (c, s) = (turn.cos(), turn.sin());
                (to.0 - 0.25 * (c * dx - s * dy), to.1 - 0.25 * (s * dx + c * dy))
            };
            chart.draw_series([
                PathElement::new(vec![*from, *to], pen),
                PathElement::new(vec![head(0.44), *to, head(-0.44)], pen),
            ])?;
            // Behind the tail, away from where it points: the words never cross the shaft.
            let length = dx.hypot(dy).max(1e-12);
            let (ux, uy) = (dx / length, dy / length);
            let h_pos = match ux {
                u if u > 0.4 => HPos::Right,
                u if u < -0.4 => HPos::Left,
                _ => HPos::Center,
            };
            let v_pos = match uy {
                u if u > 0.4 => VPos::Top,
                u if u < -0.4 => VPos::Bottom,
                _ => VPos::Center,
            };
            let gap = f64::from(style::units(3.0));
            let offset = ((-ux * gap).round() as i32, (uy * gap).round() as i32);
            chart.draw_series(std::iter::once(
                EmptyElement::at(*from) + Text::new(label.clone(), offset, note.pos(Pos::new(h_pos, v_pos))),
            ))?;
        }
        for (k, (_, band)) in self.bands.iter().enumerate() {
            let mut outline: Vec<(f64, f64)> = band.iter().map(|p| (p.0, p.2)).collect();
            outline.extend(band.iter().rev().map(|p| (p.0, p.1)));
            chart.draw_series(std::iter::once(Polygon::new(
                outline,
                style::family(k).mix(BAND).filled(),
            )))?;
        }
        for (level, _) in &self.levels {
            let (on, off) = level_dash();
            chart.draw_series(DashedLineSeries::new(
                vec![(x.0, *level), (x.1, *level)],
                on,
                off,
                style::INK.stroke_width(thin()),
            ))?;
        }
        for (k, s) in self.series.iter().enumerate() {
            let colour = style::family(k);
            let pen = colour.stroke_width(style::line_width());
            // A point without a value (a vehicle lost, then back) breaks the line there.
            for run in s.points.split(|p| !p.1.is_finite()).filter(|run| !run.is_empty()) {
                match (run, style::dash(k)) {
                    // A line through one point is drawn as nothing: a dot instead.
                    ([point], _) => {
                        chart.draw_series(std::iter::once(Circle::new(*point, style::units(2.0), colour.filled())))?;
                    }
                    (_, None) => {
                        chart.draw_series(LineSeries::new(run.iter().copied(), pen))?;
                    }
                    (_, Some((on, off))) => {
                        chart.draw_series(DashedLineSeries::new(run.iter().copied(), on, off, pen))?;
                    }
                }
            }
        }
        for (k, s) in self.dots.iter().enumerate() {
            let colour = self.dot_color(k);
            chart.draw_series(
                s.points
                    .iter()
                    .map(|&p| Circle::new(p, style::units(1.2), colour.filled())),
            )?;
        }
        let beside = note.pos(Pos::new(HPos::Left, VPos::Center));
        for (px, py, text) in &self.labels {
            chart.draw_series(std::iter::once(
                EmptyElement::at((*px, *py))
                    + Circle::new((0, 0), style::units(1.0), style::INK.filled())
                    + Text::new(text.clone(), (style::units(2.0), 0), beside.clone()),
            ))?;
        }
        for (px, py, name) in &self.markers {
            let r = style::units(2.5);
            chart.draw_series(std::iter::once(
                EmptyElement::at((*px, *py))
                    + Circle::new((0, 0), r, style::INK.stroke_width(style::line_width()))
                    + Text::new(name.clone(), (r + style::units(1.5), 0), beside.clone()),
            ))?;
        }
        if !entries.is_empty() {
            style::legend(&under, entries)?;
        }
        Ok(())
    }
}

/// The name of the category centred on `x` (category c sits at x = c), or nothing between two:
/// what a bar chart's axis writes under each group of bars.
pub fn category_at(categories: &[String], x: f64) -> String {
    let c = x.round();
    categories
        .get(c as usize)
        .filter(|_| c >= 0.0 && (x - c).abs() < 1e-6)
        .cloned()
        .unwrap_or_default()
}

/// Every how many categories a label fits along a plot `width` units wide: the widest label
/// and a space between two.
fn labelled_every(categories: &[String], width: f64) -> usize {
    let widest = categories
        .iter()
        .map(|c| text_width(c, style::TICK_PT))
        .max()
        .unwrap_or(0);
    let room = width / categories.len().max(1) as f64;
    (f64::from(widest + style::units(style::TICK_PT * 0.5)) / room)
        .ceil()
        .max(1.0) as usize
}

/// Grouped bars: per category, one bar per named value in the colour given with it (which
/// means the same in every figure), each category named under its bars, as an SVG document of
/// `size`.
pub fn bars(
    x_label: &str,
    y_label: &str,
    categories: &[String],
    groups: &[(&str, RGBColor, Vec<f64>)],
    size: Size,
) -> String {
    let (w, h) = size.pixels();
    let top = groups.iter().flat_map(|g| g.2.iter().copied()).fold(1.0f64, f64::max) * 1.1;
    let n = categories.len().max(1);
    let (x, y) = ((-0.5, n as f64 - 0.5), (0.0, top));
    let entries: Vec<(String, Swatch)> = groups
        .iter()
        .map(|(name, colour, _)| {
            (
                name.to_string(),
                Swatch::Fill {
                    colour: *colour,
                    alpha: 1.0,
                },
            )
        })
        .collect();
    let y_format = style::ticks(y, Y_TICKS);
    let layout = Layout::new(
        style::legend_height(&entries, w),
        (n, Y_TICKS),
        categories,
        &tick_labels(y, Y_TICKS, &y_format),
    );
    // Category c is centred on x = c, where the axis puts a label: on every `every`-th, so that
    // the labels of many (the 400 links of 200 vehicles) stand apart rather than run together.
    let every = labelled_every(categories, layout.plot((w, h)).0);
    let x_format = |v: &f64| match v.round() {
        c if c >= 0.0 && (c as usize).is_multiple_of(every) => category_at(categories, *v),
        _ => String::new(),
    };
    let mut out = String::new();
    {
        let root = SVGBackend::with_string(&mut out, (w, h)).into_drawing_area();
        let draw = || -> Result<(), Box<dyn std::error::Error>> {
            root.fill(&WHITE)?;
            let (upper, under) = root.split_vertically(h.saturating_sub(layout.legend));
            let mut chart = axes(
                &upper,
                &layout,
                Axis {
                    range: x,
                    desc: x_label,
                    format: &x_format,
                },
                Axis {
                    range: y,
                    desc: y_label,
                    format: &y_format,
                },
                false,
            )?;
            let width = 0.8 / groups.len().max(1) as f64;
            // A rectangle of no width or no height is no shape to a PDF's reader, which warns of
            // it: a bar of nothing is not drawn, and any other is a pixel wide and high at least
            // (the links of 200 vehicles are 800 bars).
            let (w_px, h_px) = chart.plotting_area().dim_in_pixel();
            // A pixel and a half: the corners are rounded to pixels each on its own.
            let pixel = (
                1.5 * (x.1 - x.0) / f64::from(w_px.max(1)),
                1.5 * (y.1 - y.0) / f64::from(h_px.max(1)),
            );
            for (g, (_, colour, values)) in groups.iter().enumerate() {
                chart.draw_series(values.iter().enumerate().filter(|(_, v)| **v != 0.0).map(|(c, v)| {
                    let left = c as f64 - 0.4 + g as f64 * width;
                    let top = v.signum() * v.abs().max(pixel.1);
                    Rectangle::new([(left, 0.0), (left + width.max(pixel.0), top)], colour.filled())
                }))?;
            }
            if !entries.is_empty() {
                style::legend(&under, &entries)?;
            }
            root.present()?;
            Ok(())
        };
        let _ = draw();
    }
    style::in_inches(out, size)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every text of `svg`: (its opening tag, its words).
    fn texts(svg: &str) -> Vec<(&str, &str)> {
        svg.split("</text>")
            .filter_map(|chunk| {
                let open = chunk.rfind("<text")?;
                let (tag, words) = chunk[open..].split_once(">\n")?;
                Some((tag, words.strip_suffix('\n')?))
            })
            .collect()
    }

    #[test]
    fn a_chart_draws_its_lines_labels_and_levels() {
        let mut c = Chart::new("x", "y");
        c.series.push(Series {
            name: "one".into(),
            points: vec![(0.0, 0.0), (1.0, 2.0), (2.0, 1.0)],
        });
        c.levels.push((1.5, "limit".into()));
        c.markers.push((0.0, 0.0, "start".into()));
        let size = Size::column(0.62);
        let svg = c.svg(size);
        assert!(svg.starts_with("<svg") && svg.contains("</svg>"));
        assert!(svg.contains("width=\"3.500in\""), "printed at a column's width");
        // A gap breaks it in two, named once.
        c.series[0].points = vec![(0.0, 0.0), (1.0, 2.0), (2.0, f64::NAN), (3.0, 1.0), (4.0, 0.5)];
        let gapped = c.svg(size);
        let blue = format!(
            "stroke=\"#{:02X}{:02X}{:02X}\"",
            style::family(0).0,
            style::family(0).1,
            style::family(0).2
        );
        let lines = |svg: &str| {
            svg.lines()
                .filter(|l| l.starts_with("<polyline") && l.contains(&blue))
                .count()
        };
        // The line and its legend; then two runs and the one legend.
        assert_eq!((lines(&svg), lines(&gapped)), (2, 3), "{gapped}");
        assert_eq!(gapped.matches("\none\n").count(), 1);
        assert!(svg.contains("\none\n") && svg.contains("\nlimit\n") && svg.contains("\nstart\n"));
    }

    #[test]
    fn a_chart_prints_its_words_at_8_pt_or_more_in_its_own_colours_and_no_title() {
        let mut c = Chart::new("t (s)", "|γi − γj| (s)").with_windows(&[(1.0, 2.0), (3.0, 3.0)]);
        for k in 0..3 {
            c.series.push(Series {
                name: format!("{k}–{}", k + 1),
                points: (0..50)
                    .map(|i| (0.1 * i as f64, (0.3 * i as f64 + k as f64).sin()))
                    .collect(),
            });
        }
        c.bands
            .push(("spread".into(), vec![(0.0, -1.0, 1.0), (4.9, -0.5, 0.5)]));
        c.levels.push((0.8, "limit 0.8 s".into()));
        c.labels.push((2.0, 0.0, "20".into()));
        let svg = c.svg(Size::column(0.62));
        let sizes = style::printed_text_sizes(&svg);
        assert!(sizes.len() > 10, "{sizes:?}");
        assert!(sizes.iter().all(|pt| *pt >= 8.0), "{sizes:?}");
        let upper = svg.to_uppercase();
        assert!(
            !upper.contains("#E6194B") && !upper.contains("#3CB44B"),
            "Palette99's red and green"
        );
        assert!(
            texts(&svg)
                .iter()
                .all(|(_, words)| *words != "Coordination error |γi − γj|"),
            "the caption names the figure, not a title in it"
        );
        for entry in ["0–1", "spread", "limit 0.8 s", "fault window", "fault instant"] {
            assert!(
                texts(&svg).iter().any(|(_, words)| *words == entry),
                "{entry} in the legend"
            );
        }
    }

    #[test]
    fn a_categorical_axis_writes_its_rows_alone() {
        let mut c = Chart::new("t (s)", "link");
        c.y_categories = vec!["1→2".into(), "2→1".into()];
        c.dots.push(Series {
            name: "delivered".into(),
            points: vec![(0.0, 0.0), (1.0, 1.0), (2.5, 0.0)],
        });
        let svg = c.svg(Size::column(0.4));
        // The y axis' labels are the ones right-aligned against it.
        let y_labels: Vec<(&str, &str)> = texts(&svg)
            .into_iter()
            .filter(|(tag, _)| tag.contains("text-anchor=\"end\""))
            .collect();
        let words: Vec<&str> = y_labels.iter().map(|(_, w)| *w).collect();
        // Those two alone: no 0.5, 1.1 or 1.5 between them.
        assert_eq!(words, ["1→2", "2→1"], "{svg}");
        // Row 0 at the bottom.
        let at = |tag: &str| -> i32 {
            tag.split(" y=\"")
                .nth(1)
                .unwrap()
                .split('"')
                .next()
                .unwrap()
                .parse()
                .unwrap()
        };
        assert!(at(y_labels[0].0) > at(y_labels[1].0));
    }

    /// The links of a ring of `values.len()` vehicles as bars, each delivering and dropping
    /// its value: their names and the figure.
    fn ring_links(values: Vec<f64>) -> (Vec<String>, String) {
        let n = values.len();
        let names: Vec<String> = (1..=n).map(|i| format!("{i}→{}", i % n + 1)).collect();
        let svg = bars(
            "directed link",
            "messages",
            &names,
            &[
                ("delivered", style::DELIVERED, values.clone()),
                ("dropped", style::LOST, values),
            ],
            Size::column(0.62),
        );
        (names, svg)
    }

    #[test]
    fn every_bar_is_a_pixel_wide_and_high_at_least() {
        let n = 400;
        let values: Vec<f64> = (0..n).map(|i| if i == 7 { 1e-3 } else { 500.0 }).collect();
        let (_, svg) = ring_links(values);
        assert!(svg.matches("<rect").count() >= 2 * n, "every value is drawn");
        for empty in ["width=\"0\"", "height=\"0\""] {
            assert!(!svg.contains(empty), "a rectangle with {empty}");
        }
    }

    #[test]
    fn the_labels_of_many_categories_stand_apart() {
        let (names, svg) = ring_links(vec![5.0; 400]);
        let labels: Vec<&str> = texts(&svg)
            .into_iter()
            .map(|(_, words)| words)
            .filter(|w| names.iter().any(|n| n == w))
            .collect();
        // "399→400" is half an inch at 8 pt: a column's plot (under 3 in) holds a few.
        assert!((4..=8).contains(&labels.len()), "{} labels: {labels:?}", labels.len());
        assert_eq!(labels[0], "1→2", "the first category is named");
        let every = names.iter().position(|n| n == labels[1]).expect("a category");
        assert!(
            labels.iter().zip(names.iter().step_by(every)).all(|(l, n)| l == n),
            "every {every}-th"
        );
    }

    #[test]
    fn bars_have_one_rectangle_per_value() {
        for n in [2, 6] {
            let (names, svg) = ring_links(vec![5.0; n]);
            assert!(svg.matches("<rect").count() >= 2 * n, "{svg}");
            assert!(svg.contains("\ndelivered\n") && svg.contains("directed link"));
            assert!(style::printed_text_sizes(&svg).iter().all(|pt| *pt >= 8.0));
            for name in &names {
                assert!(
                    svg.contains(&format!(">\n{name}\n<")),
                    "{name} is under its bars: {svg}"
                );
            }
        }
    }
}
