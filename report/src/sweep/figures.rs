//! A sweep's figures, sized for a paper's column (`crate::style`): per metric, the mean over the
//! seeds against the first swept key, one curve per combination of the others (a family),
//! markers at the sampled values, a band (95 % interval of the mean, or min–max), requirement
//! lines, and the legend under the plot, never over it. A categorical first key (a topology)
//! gets bars with the band as whiskers. Family k has the same colour, marker and dash in every
//! figure. No title inside: each figure's caption is beside it in sweep.html and in
//! `<figure>.txt`.

use std::path::Path;

use plotters::prelude::*;

use super::{PointSummary, Stats, SweepSummary};
use crate::error::Result;
use crate::labels;
use crate::style::{self, Marker, Size, Swatch};

/// What the band around a mean shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Band {
    /// The 95 % confidence interval of the mean (Student's t).
    #[default]
    Ci95,
    /// The smallest and largest value of the seeds.
    MinMax,
}

impl Band {
    fn of(self, s: &Stats) -> (f64, f64) {
        match self {
            Band::Ci95 => {
                let ci = s.ci95.unwrap_or(0.0);
                (s.mean - ci, s.mean + ci)
            }
            Band::MinMax => (s.min, s.max),
        }
    }

    fn name(self) -> &'static str {
        match self {
            Band::Ci95 => "the 95 % confidence interval of the mean",
            Band::MinMax => "the smallest and largest value over the seeds",
        }
    }
}

/// How a sweep's figures are drawn.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Look {
    pub band: Band,
    /// in: the printed width (`style::COLUMN` by default).
    pub width: f64,
}

impl Default for Look {
    fn default() -> Look {
        Look {
            band: Band::Ci95,
            width: style::COLUMN,
        }
    }
}

impl Look {
    /// The flags of `tcpf sweep` that draw this look (none for the default one).
    pub fn flags(self) -> Vec<String> {
        let mut flags = Vec::new();
        if self.band == Band::MinMax {
            flags.extend(["--band".into(), "min-max".into()]);
        }
        if self.width != style::COLUMN {
            let width = if self.width == style::DOUBLE_COLUMN {
                "double".to_string()
            } else {
                self.width.to_string()
            };
            flags.extend(["--figure-width".into(), width]);
        }
        flags
    }
}

/// A figure's height as a share of its width, legend aside.
const ASPECT: f64 = 0.62;
/// Labels along an axis, at most.
const X_TICKS: usize = 6;
const Y_TICKS: usize = 5;

/// A requirement line: its value and its name in the legend.
type Level = (f64, String);

/// What one figure shows.
struct Plot<'a> {
    metric: &'a str,
    band: Band,
    level: Option<&'a Level>,
    size: Size,
}

/// The figures' metrics: (metric, file, a requirement line of the mission if it has one).
fn plotted(summary: &SweepSummary) -> Vec<(&'static str, &'static str, Option<Level>)> {
    let mut v = vec![
        ("max_coordination_error", "sweep-error", None),
        ("rms_coordination_error", "sweep-rms", None),
        (
            "min_clearance",
            "sweep-clearance",
            Some((
                summary.design.clearance,
                format!("required clearance E = {} m", summary.design.clearance),
            )),
        ),
        ("last_arrival", "sweep-arrival", None),
        ("messages_per_vehicle_s", "sweep-messages", None),
    ];
    // Only a sweep with fault windows has re-synchronisations to show.
    if summary.points.iter().any(|p| p.get("resync_time").is_some()) {
        v.insert(2, ("resync_time", "sweep-resync", None));
    }
    v
}

/// A family: the points of the sweep at one combination of every key but the first, in the
/// order of the first key's values.
struct Family<'a> {
    name: String,
    points: Vec<(usize, &'a PointSummary)>,
}

fn families(summary: &SweepSummary) -> Vec<Family<'_>> {
    let grid = &summary.design.grid;
    let mut out: Vec<Family> = Vec::new();
    for p in &summary.points {
        let rest: Vec<String> = grid.params[1..]
            .iter()
            .zip(&p.values[1..])
            .map(|(k, v)| labels::key(&k.key).value(v))
            .collect();
        let name = if rest.is_empty() {
            format!("mean of {} seed{}", grid.seeds, if grid.seeds == 1 { "" } else { "s" })
        } else {
            rest.join(", ")
        };
        let x = grid.params[0]
            .values
            .iter()
            .position(|v| *v == p.values[0])
            .unwrap_or(0);
        match out.iter_mut().find(|f| f.name == name) {
            Some(f) => f.points.push((x, p)),
            None => out.push(Family {
                name,
                points: vec![(x, p)],
            }),
        }
    }
    out
}

/// The value of `metric` if every run of every grid point gave it to three significant digits
/// (broadcasts per second that move only with when the fleet arrived): a figure of it would be
/// a flat line. One grid point is drawn whatever it is: nothing is constant across one value.
fn constant(summary: &SweepSummary, metric: &str) -> Option<f64> {
    let stats: Vec<Stats> = summary.points.iter().filter_map(|p| p.get(metric)).collect();
    let lo = stats.iter().map(|s| s.min).fold(f64::INFINITY, f64::min);
    let hi = stats.iter().map(|s| s.max).fold(f64::NEG_INFINITY, f64::max);
    (stats.len() > 1 && significant(lo) == significant(hi)).then(|| significant(lo))
}

/// `x` to three significant digits.
fn significant(x: f64) -> f64 {
    if x == 0.0 || !x.is_finite() {
        return x;
    }
    let scale = 10f64.powi(2 - x.abs().log10().floor() as i32);
    (x * scale).round() / scale
}

/// Writes every figure as SVG, PDF and its caption (`<file>.txt`), and returns their HTML.
/// Says in `table` what is not drawn, and why.
pub fn write(out: &Path, summary: &SweepSummary, look: Look, table: &mut String) -> Result<String> {
    let grid = &summary.design.grid;
    // Seeds alone (a bench's sweep) have no axis to draw against.
    let Some(first) = grid.params.first() else {
        return Ok(String::new());
    };
    if summary.points.is_empty() {
        table.push_str("no figures: no run is done\n");
        return Ok(String::new());
    }
    let xs: Option<Vec<f64>> = first.values.iter().map(|v| v.parse::<f64>().ok()).collect();
    let families = families(summary);
    let mut html = String::new();
    for (metric, file, level) in plotted(summary) {
        let label = labels::metric(metric);
        if let Some(value) = constant(summary, metric) {
            let value = value.to_string();
            table.push_str(&format!(
                "{}: {} in every run, to three significant digits (no figure)\n",
                label.name,
                match label.unit {
                    "" => value,
                    unit => format!("{value} {unit}"),
                }
            ));
            continue;
        }
        let plot = Plot {
            metric,
            band: look.band,
            level: level.as_ref(),
            size: Size::column(ASPECT).with_width(look.width),
        };
        let svg = match &xs {
            Some(xs) => lines(summary, &families, xs, &plot),
            None => bars(summary, &families, &plot),
        };
        let caption = caption(summary, metric, look.band, families.len());
        html.push_str(&save(out, file, &svg, &caption)?);
    }
    Ok(html)
}

/// Writes figure `file` as SVG, PDF and its caption (`<file>.txt`); returns it as sweep.html
/// shows it, its caption under it.
fn save(out: &Path, file: &str, svg: &str, caption: &str) -> Result<String> {
    std::fs::write(out.join(format!("{file}.svg")), svg)?;
    std::fs::write(out.join(format!("{file}.pdf")), crate::pdf::of_svg(svg)?)?;
    std::fs::write(out.join(format!("{file}.txt")), format!("{caption}\n"))?;
    Ok(format!(
        "<figure class=\"plot\" id=\"{file}\">{svg}<figcaption>{}</figcaption></figure>\n",
        super::escape(caption)
    ))
}

/// What a figure shows, in words: the caption a paper puts under it.
fn caption(summary: &SweepSummary, metric: &str, band: Band, families: usize) -> String {
    let grid = &summary.design.grid;
    let label = labels::metric(metric);
    let mut s = format!(
        "{} against {}: the mean over {} seed{} at each value",
        capitalised(label.name),
        labels::key(&grid.params[0].key).name,
        grid.seeds,
        if grid.seeds == 1 { "" } else { "s" }
    );
    if families > 1 {
        let others: Vec<&str> = grid.params[1..].iter().map(|p| labels::key(&p.key).name).collect();
        s.push_str(&format!(", one line per {}", others.join(" and ")));
    }
    s.push_str(&format!("; the band is {}.", band.name()));
    if metric == "last_arrival" || metric == "arrival_spread" {
        s.push_str(" Over the runs in which every vehicle arrived.");
    }
    s
}

fn capitalised(s: &str) -> String {
    let mut c = s.chars();
    c.next().map_or(String::new(), |f| f.to_uppercase().chain(c).collect())
}

type Area<'a> = DrawingArea<SVGBackend<'a>, plotters::coord::Shift>;

type Chart<'a, 'b> = ChartContext<
    'a,
    SVGBackend<'b>,
    Cartesian2d<plotters::coord::types::RangedCoordf64, plotters::coord::types::RangedCoordf64>,
>;

/// The plot's area and the legend's under it.
fn areas<'a>(root: &Area<'a>, entries: &[(String, Swatch)]) -> (Area<'a>, Area<'a>) {
    let (w, h) = root.dim_in_pixel();
    root.split_vertically(h - style::legend_height(entries, w))
}

/// A figure's last marks: the requirement line across `x`, if the figure has one.
fn level_line(chart: &mut Chart, x: (f64, f64), level: Option<&Level>) -> Result<(), Box<dyn std::error::Error>> {
    if let Some((y, _)) = level {
        let style = ShapeStyle::from(&BLACK).stroke_width(style::line_width());
        chart.draw_series(DashedLineSeries::new(
            vec![(x.0, *y), (x.1, *y)],
            style::units(4.0),
            style::units(2.5),
            style,
        ))?;
    }
    Ok(())
}

/// The legend's entries: the families, then the requirement line.
fn entries(families: &[Family], level: Option<&Level>, bars: bool) -> Vec<(String, Swatch)> {
    let mut entries: Vec<(String, Swatch)> = families
        .iter()
        .enumerate()
        .map(|(k, f)| {
            let swatch = if bars {
                Swatch::Bar {
                    colour: style::family(k),
                    marker: Marker::of(k),
                }
            } else {
                Swatch::Band {
                    colour: style::family(k),
                    dash: style::dash(k),
                    marker: Marker::of(k),
                }
            };
            (f.name.clone(), swatch)
        })
        .collect();
    if let Some((_, name)) = level {
        entries.push((
            name.clone(),
            Swatch::Line {
                colour: style::INK,
                dash: Some((style::units(4.0), style::units(2.5))),
                marker: None,
            },
        ));
    }
    entries
}

fn axis_range(lo: f64, hi: f64, from_zero: bool) -> (f64, f64) {
    let lo = if from_zero { lo.min(0.0) } else { lo };
    if !(lo.is_finite() && hi.is_finite()) {
        (0.0, 1.0)
    } else if hi - lo < 1e-9 {
        (lo - 0.5, hi + 0.5)
    } else {
        let pad = 0.06 * (hi - lo);
        (if from_zero && lo >= 0.0 { 0.0 } else { lo - pad }, hi + pad)
    }
}

/// A chart on `plot` with the figure's axes, fonts and ticks.
fn chart<'a, 'b>(
    plot: &'a Area<'b>,
    x: (f64, f64),
    y: (f64, f64),
    x_desc: &str,
    y_desc: &str,
    categories: Option<&[String]>,
) -> Result<Chart<'a, 'b>, Box<dyn std::error::Error>> {
    let mut chart = ChartBuilder::on(plot)
        .margin(style::units(5.0))
        .margin_left(style::units(2.0))
        .x_label_area_size(style::units(24.0))
        .y_label_area_size(style::units(34.0))
        .build_cartesian_2d(x.0..x.1, y.0..y.1)?;
    let x_ticks = style::ticks(x, X_TICKS);
    let y_ticks = style::ticks(y, Y_TICKS);
    let category = |v: &f64| crate::plots::category_at(categories.unwrap_or_default(), *v);
    let mut mesh = chart.configure_mesh();
    mesh.x_desc(x_desc)
        .y_desc(y_desc)
        .y_labels(Y_TICKS)
        .y_label_formatter(&y_ticks)
        .label_style(style::font(style::TICK_PT))
        .axis_desc_style(style::font(style::LABEL_PT))
        .axis_style(BLACK.stroke_width(style::line_width()))
        .set_all_tick_mark_size(style::units(2.5))
        .light_line_style(TRANSPARENT)
        .bold_line_style(RGBColor(225, 225, 225).stroke_width(1));
    match categories {
        Some(c) => mesh.disable_x_mesh().x_labels(c.len()).x_label_formatter(&category),
        None => mesh.x_labels(X_TICKS).x_label_formatter(&x_ticks),
    };
    mesh.draw()?;
    Ok(chart)
}

/// The figure `draw` makes on a root of `size`, in inches.
fn figure(size: Size, draw: impl FnOnce(&Area) -> Result<(), Box<dyn std::error::Error>>) -> String {
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, size.pixels()).into_drawing_area();
        let drawn = root.fill(&WHITE).map_err(Into::into).and_then(|()| draw(&root));
        if let Err(e) = drawn.and_then(|()| root.present().map_err(Into::into)) {
            tracing::warn!("a sweep figure is incomplete: {e}");
        }
    }
    style::in_inches(svg, size)
}

fn lines(summary: &SweepSummary, families: &[Family], xs: &[f64], plot: &Plot) -> String {
    let Plot {
        metric,
        band,
        level,
        size,
    } = *plot;
    let legend = entries(families, level, false);
    figure(size, |root| {
        let (area, side) = areas(root, &legend);
        let stats: Vec<(f64, Stats)> = families
            .iter()
            .flat_map(|f| f.points.iter().filter_map(|(x, p)| p.get(metric).map(|s| (xs[*x], s))))
            .collect();
        let (x0, x1) = axis_range(
            xs.iter().copied().fold(f64::INFINITY, f64::min),
            xs.iter().copied().fold(f64::NEG_INFINITY, f64::max),
            false,
        );
        let ys = stats
            .iter()
            .flat_map(|(_, s)| {
                let (lo, hi) = band.of(s);
                [lo, hi, s.mean]
            })
            .chain(level.map(|l| l.0));
        let (lo, hi) = ys.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), y| (a.min(y), b.max(y)));
        let y = axis_range(lo, hi, metric == "messages_per_vehicle_s");
        let x_desc = labels::key(&summary.design.grid.params[0].key).axis();
        let mut chart = chart(&area, (x0, x1), y, &x_desc, &labels::metric(metric).axis(), None)?;
        for (k, f) in families.iter().enumerate() {
            let points: Vec<(f64, Stats)> = f
                .points
                .iter()
                .filter_map(|(x, p)| p.get(metric).map(|s| (xs[*x], s)))
                .collect();
            if points.is_empty() {
                continue;
            }
            let rows: Vec<(f64, f64, (f64, f64))> = points.iter().map(|(x, s)| (*x, s.mean, band.of(s))).collect();
            family(&mut chart, k, &rows, 1)?;
        }
        level_line(&mut chart, (x0, x1), level)?;
        style::legend(&side, &legend)
    })
}

/// Family `k`'s mean (x, mean, (low, high)) as a line in its colour and dash over its band, with
/// its marker on every `every`-th point.
fn family(
    chart: &mut Chart,
    k: usize,
    rows: &[(f64, f64, (f64, f64))],
    every: usize,
) -> Result<(), Box<dyn std::error::Error>> {
    let c = style::family(k);
    let mut outline: Vec<(f64, f64)> = rows.iter().map(|(x, _, band)| (*x, band.1)).collect();
    outline.extend(rows.iter().rev().map(|(x, _, band)| (*x, band.0)));
    chart.draw_series(std::iter::once(Polygon::new(
        outline,
        c.mix(style::BAND_ALPHA).filled(),
    )))?;
    let means = rows.iter().map(|(x, mean, _)| (*x, *mean));
    let stroke = c.stroke_width(style::line_width());
    match style::dash(k) {
        None => chart.draw_series(LineSeries::new(means, stroke))?,
        Some((on, off)) => chart.draw_series(DashedLineSeries::new(means, on, off, stroke))?,
    };
    let marker = Marker::of(k).outline(style::units(2.2));
    chart.draw_series(
        rows.iter()
            .skip(every / 2)
            .step_by(every)
            .map(|(x, mean, _)| EmptyElement::at((*x, *mean)) + Polygon::new(marker.clone(), c.filled())),
    )?;
    Ok(())
}

fn bars(summary: &SweepSummary, families: &[Family], plot: &Plot) -> String {
    let Plot {
        metric,
        band,
        level,
        size,
    } = *plot;
    let categories = &summary.design.grid.params[0].values;
    let legend = entries(families, level, true);
    figure(size, |root| {
        let (area, side) = areas(root, &legend);
        let hi = families
            .iter()
            .flat_map(|f| f.points.iter().filter_map(|(_, p)| p.get(metric)))
            .map(|s| band.of(&s).1.max(s.mean))
            .chain(level.map(|l| l.0))
            .fold(0.0f64, f64::max);
        let (_, top) = axis_range(0.0, hi, true);
        let n = categories.len().max(1);
        let x = (-0.5, n as f64 - 0.5);
        let x_desc = labels::key(&summary.design.grid.params[0].key).axis();
        let mut chart = chart(
            &area,
            x,
            (0.0, top),
            &x_desc,
            &labels::metric(metric).axis(),
            Some(categories),
        )?;
        let w = 0.8 / families.len().max(1) as f64;
        let thin = BLACK.stroke_width(style::line_width());
        for (k, f) in families.iter().enumerate() {
            let c = style::family(k);
            let outline = Marker::of(k).outline(style::units(2.0));
            for (x, p) in &f.points {
                let Some(s) = p.get(metric) else { continue };
                let left = *x as f64 - 0.4 + k as f64 * w;
                let mid = left + 0.5 * w;
                // A bar of nothing is no rectangle (a PDF's reader warns of one of no height).
                if s.mean != 0.0 {
                    chart.draw_series(std::iter::once(Rectangle::new(
                        [(left + 0.05 * w, 0.0), (left + 0.95 * w, s.mean)],
                        c.mix(style::BAR_ALPHA).filled(),
                    )))?;
                }
                let (lo, hi) = band.of(&s);
                let whisker = |y| PathElement::new(vec![(mid - 0.2 * w, y), (mid + 0.2 * w, y)], thin);
                chart.draw_series([
                    PathElement::new(vec![(mid, lo), (mid, hi)], thin),
                    whisker(lo),
                    whisker(hi),
                ])?;
                // Its family's marker on it, told apart in grey print.
                chart.draw_series(std::iter::once(
                    EmptyElement::at((mid, s.mean)) + Polygon::new(outline.clone(), style::INK.filled()),
                ))?;
            }
        }
        level_line(&mut chart, x, level)?;
        style::legend(&side, &legend)
    })
}

/// The series' figures (`series-error`, `series-clearance`): per grid point, the mean over the
/// seeds against time with its 95 % interval as a band. Returns their HTML.
pub fn series(out: &Path, summary: &SweepSummary, series: &super::series::Series, look: Look) -> Result<String> {
    let grid = &summary.design.grid;
    let stats = series.stats();
    let mut html = String::new();
    for (file, which, label, level) in [
        ("series-error", 0, labels::metric("max_coordination_error"), None),
        (
            "series-clearance",
            1,
            labels::metric("min_clearance"),
            Some((
                summary.design.clearance,
                format!("required clearance E = {} m", summary.design.clearance),
            )),
        ),
    ] {
        let name = |k: usize| {
            let values = grid.values(k as u64);
            let words: Vec<String> = grid
                .params
                .iter()
                .zip(values)
                .map(|(p, v)| labels::key(&p.key).value(v))
                .collect();
            if words.is_empty() {
                "mean".to_string()
            } else {
                words.join(", ")
            }
        };
        let mut legend: Vec<(String, Swatch)> = stats
            .iter()
            .enumerate()
            .map(|(f, (k, _))| {
                (
                    name(*k),
                    Swatch::Band {
                        colour: style::family(f),
                        dash: style::dash(f),
                        marker: Marker::of(f),
                    },
                )
            })
            .collect();
        if let Some((_, words)) = &level {
            legend.push((
                words.clone(),
                Swatch::Line {
                    colour: style::INK,
                    dash: Some((style::units(4.0), style::units(2.5))),
                    marker: None,
                },
            ));
        }
        let pick = |row: &(f64, Stats, Stats)| if which == 0 { row.1 } else { row.2 };
        let svg = figure(Size::column(ASPECT).with_width(look.width), |root| {
            let (area, side) = areas(root, &legend);
            let t1 = stats
                .iter()
                .flat_map(|(_, rows)| rows.last().map(|r| r.0))
                .fold(0.0, f64::max);
            let (lo, hi) = stats
                .iter()
                .flat_map(|(_, rows)| rows.iter().map(pick))
                .flat_map(|s| {
                    let ci = s.ci95.unwrap_or(0.0);
                    [s.mean - ci, s.mean + ci]
                })
                .chain(level.as_ref().map(|l| l.0))
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), y| (a.min(y), b.max(y)));
            let y = axis_range(lo, hi, true);
            let mut chart = chart(&area, (0.0, t1.max(1e-9)), y, "time (s)", &label.axis(), None)?;
            for (f, (_, rows)) in stats.iter().enumerate() {
                let rows: Vec<(f64, f64, (f64, f64))> = rows
                    .iter()
                    .map(|r| {
                        let s = pick(r);
                        (r.0, s.mean, Band::Ci95.of(&s))
                    })
                    .collect();
                // A marker every tenth of the way: the family's shape, in grey print too.
                family(&mut chart, f, &rows, (rows.len() / 10).max(1))?;
            }
            level_line(&mut chart, (0.0, t1), level.as_ref())?;
            style::legend(&side, &legend)
        });
        let caption = format!(
            "{} against time: the mean over {} seed{} of each grid point, sampled every {} s; the band is the 95 % confidence interval of the mean.",
            capitalised(label.name),
            grid.seeds,
            if grid.seeds == 1 { "" } else { "s" },
            super::series::STEP
        );
        html.push_str(&save(out, file, &svg, &caption)?);
    }
    Ok(html)
}
