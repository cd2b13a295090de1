//! A sweep's figures, sized for a paper's column: per metric, the mean over the seeds against
//! the first swept key, one curve per combination of the others (a family), markers at the
//! sampled values, a band (95 % interval of the mean, or min–max), requirement lines, and the
//! legend beside the plot, never over it. A categorical first key (a topology) gets bars with
//! the band as whiskers. Family k has the same colour in every figure.

use std::path::Path;

use anyhow::Result;
use plotters::prelude::*;

use super::{PointSummary, Stats, SweepSummary};

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
            Band::Ci95 => "band: 95 % CI of the mean",
            Band::MinMax => "band: min–max over the seeds",
        }
    }
}

/// Pixels of a figure: at a column's 3.5 in, 13 px ticks print at 7.6 pt.
const SIZE: (u32, u32) = (600, 340);
const LEGEND: u32 = 170;
const FONT: &str = "sans-serif";

/// A requirement line: its value and its name in the legend.
type Level = (f64, String);

/// What one figure shows.
struct Plot<'a> {
    metric: &'a str,
    title: &'a str,
    unit: &'a str,
    band: Band,
    level: Option<&'a Level>,
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
                format!("required E = {} m", summary.design.clearance),
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
            .map(|(k, v)| format!("{} = {v}", short(&k.key)))
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

/// `comms.delay` as a legend says it: `delay`.
fn short(key: &str) -> &str {
    key.rsplit('.').next().unwrap_or(key)
}

/// Writes every figure as SVG and PDF, and returns their HTML.
/// Says in `table` what cannot be drawn.
pub fn write(out: &Path, summary: &SweepSummary, band: Band, table: &mut String) -> Result<String> {
    let grid = &summary.design.grid;
    // Seeds alone (a bench's sweep) have no axis to draw against.
    let Some(first) = grid.params.first() else {
        return Ok(String::new());
    };
    let xs: Option<Vec<f64>> = first.values.iter().map(|v| v.parse::<f64>().ok()).collect();
    let families = families(summary);
    let mut html = String::new();
    for (metric, file, level) in plotted(summary) {
        let m = &super::METRICS[super::row::metric(metric)];
        let plot = Plot {
            metric,
            title: m.title,
            unit: m.unit,
            band,
            level: level.as_ref(),
        };
        let svg = match &xs {
            Some(xs) => lines(summary, &families, xs, &plot),
            None => bars(summary, &families, &plot),
        };
        std::fs::write(out.join(format!("{file}.svg")), &svg)?;
        std::fs::write(out.join(format!("{file}.pdf")), crate::pdf::of_svg(&svg)?)?;
        html.push_str(&format!("<figure class=\"plot\" id=\"{file}\">{svg}</figure>\n"));
    }
    if summary.points.is_empty() {
        table.push_str("no figures: no run is done\n");
    }
    Ok(html)
}

fn color(k: usize) -> RGBColor {
    // Okabe–Ito: told apart by readers with a colour vision deficiency, and in grey print.
    const PALETTE: [RGBColor; 7] = [
        RGBColor(0, 114, 178),
        RGBColor(213, 94, 0),
        RGBColor(0, 158, 115),
        RGBColor(204, 121, 167),
        RGBColor(230, 159, 0),
        RGBColor(86, 180, 233),
        RGBColor(0, 0, 0),
    ];
    PALETTE[k % PALETTE.len()]
}

type Area<'a> = DrawingArea<SVGBackend<'a>, plotters::coord::Shift>;

/// The legend, in its own area right of the plot: (name, colour or None for a requirement line).
fn legend(area: &Area, entries: &[(String, Option<RGBColor>)], band: Band) -> Result<(), Box<dyn std::error::Error>> {
    let mut y = 50;
    let text = (FONT, 13).into_font();
    for (name, c) in entries {
        match c {
            Some(c) => {
                area.draw(&PathElement::new(vec![(4, y), (28, y)], c.stroke_width(2)))?;
                area.draw(&Circle::new((16, y), 3, c.filled()))?;
            }
            None => {
                area.draw(&PathElement::new(vec![(4, y), (12, y)], BLACK.stroke_width(1)))?;
                area.draw(&PathElement::new(vec![(18, y), (28, y)], BLACK.stroke_width(1)))?;
            }
        }
        area.draw(&Text::new(name.clone(), (34, y - 7), text.clone()))?;
        y += 20;
    }
    area.draw(&Rectangle::new([(4, y - 5), (28, y + 5)], BLACK.mix(0.15).filled()))?;
    area.draw(&Text::new(band.name().to_string(), (34, y - 7), (FONT, 11).into_font()))?;
    Ok(())
}

type Chart<'a, 'b> = ChartContext<
    'a,
    SVGBackend<'b>,
    Cartesian2d<plotters::coord::types::RangedCoordf64, plotters::coord::types::RangedCoordf64>,
>;

/// A figure's last marks: the requirement line across `x`, if the figure has one, then the
/// legend of `entries` and it beside the plot.
fn finish(
    chart: &mut Chart,
    x: (f64, f64),
    level: Option<&Level>,
    mut entries: Vec<(String, Option<RGBColor>)>,
    side: &Area,
    band: Band,
) -> Result<(), Box<dyn std::error::Error>> {
    if let Some((y, name)) = level {
        let style = ShapeStyle::from(&BLACK).stroke_width(1);
        chart.draw_series(DashedLineSeries::new(vec![(x.0, *y), (x.1, *y)], 6, 4, style))?;
        entries.push((name.clone(), None));
    }
    legend(side, &entries, band)
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

fn lines(summary: &SweepSummary, families: &[Family], xs: &[f64], plot: &Plot) -> String {
    let Plot {
        metric,
        title,
        unit,
        band,
        level,
    } = *plot;
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, SIZE).into_drawing_area();
        let draw = || -> Result<(), Box<dyn std::error::Error>> {
            root.fill(&WHITE)?;
            let (plot, side) = root.split_horizontally(SIZE.0 - LEGEND);
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
            let (y0, y1) = axis_range(lo, hi, metric == "messages_per_vehicle_s");
            let mut chart = ChartBuilder::on(&plot)
                .caption(title, (FONT, 17))
                .margin(10)
                .x_label_area_size(42)
                .y_label_area_size(62)
                .build_cartesian_2d(x0..x1, y0..y1)?;
            chart
                .configure_mesh()
                .x_desc(summary.design.grid.params[0].key.as_str())
                .y_desc(unit)
                .label_style((FONT, 13))
                .axis_desc_style((FONT, 14))
                .light_line_style(TRANSPARENT)
                .draw()?;
            let mut entries = Vec::new();
            for (k, f) in families.iter().enumerate() {
                let c = color(k);
                let points: Vec<(f64, Stats)> = f
                    .points
                    .iter()
                    .filter_map(|(x, p)| p.get(metric).map(|s| (xs[*x], s)))
                    .collect();
                if points.is_empty() {
                    continue;
                }
                let mut outline: Vec<(f64, f64)> = points.iter().map(|(x, s)| (*x, band.of(s).1)).collect();
                outline.extend(points.iter().rev().map(|(x, s)| (*x, band.of(s).0)));
                chart.draw_series(std::iter::once(Polygon::new(outline, c.mix(0.12).filled())))?;
                // Its edges in its colour: overlapping bands stay told apart.
                for edge in [0, 1] {
                    let side = points.iter().map(|(x, s)| {
                        let (lo, hi) = band.of(s);
                        (*x, if edge == 0 { lo } else { hi })
                    });
                    chart.draw_series(LineSeries::new(side, c.mix(0.5).stroke_width(1)))?;
                }
                chart.draw_series(LineSeries::new(
                    points.iter().map(|(x, s)| (*x, s.mean)),
                    c.stroke_width(2),
                ))?;
                chart.draw_series(points.iter().map(|(x, s)| Circle::new((*x, s.mean), 3, c.filled())))?;
                entries.push((f.name.clone(), Some(c)));
            }
            finish(&mut chart, (x0, x1), level, entries, &side, band)?;
            root.present()?;
            Ok(())
        };
        let _ = draw();
    }
    svg
}

fn bars(summary: &SweepSummary, families: &[Family], plot: &Plot) -> String {
    let Plot {
        metric,
        title,
        unit,
        band,
        level,
    } = *plot;
    let categories = &summary.design.grid.params[0].values;
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, SIZE).into_drawing_area();
        let draw = || -> Result<(), Box<dyn std::error::Error>> {
            root.fill(&WHITE)?;
            let (plot, side) = root.split_horizontally(SIZE.0 - LEGEND);
            let hi = families
                .iter()
                .flat_map(|f| f.points.iter().filter_map(|(_, p)| p.get(metric)))
                .map(|s| band.of(&s).1.max(s.mean))
                .chain(level.map(|l| l.0))
                .fold(0.0f64, f64::max);
            let (_, top) = axis_range(0.0, hi, true);
            let n = categories.len().max(1);
            let mut chart = ChartBuilder::on(&plot)
                .caption(title, (FONT, 17))
                .margin(10)
                .x_label_area_size(42)
                .y_label_area_size(62)
                .build_cartesian_2d(-0.5..n as f64 - 0.5, 0.0..top)?;
            chart
                .configure_mesh()
                .disable_x_mesh()
                .x_labels(n)
                .x_label_formatter(&|x| crate::plots::category_at(categories, *x))
                .x_desc(summary.design.grid.params[0].key.as_str())
                .y_desc(unit)
                .label_style((FONT, 13))
                .axis_desc_style((FONT, 14))
                .draw()?;
            let w = 0.8 / families.len().max(1) as f64;
            let mut entries = Vec::new();
            for (k, f) in families.iter().enumerate() {
                let c = color(k);
                for (x, p) in &f.points {
                    let Some(s) = p.get(metric) else { continue };
                    let left = *x as f64 - 0.4 + k as f64 * w;
                    let mid = left + 0.5 * w;
                    chart.draw_series(std::iter::once(Rectangle::new(
                        [(left + 0.05 * w, 0.0), (left + 0.95 * w, s.mean)],
                        c.mix(0.75).filled(),
                    )))?;
                    let (lo, hi) = band.of(&s);
                    let whisker =
                        |y| PathElement::new(vec![(mid - 0.2 * w, y), (mid + 0.2 * w, y)], BLACK.stroke_width(1));
                    chart.draw_series([
                        PathElement::new(vec![(mid, lo), (mid, hi)], BLACK.stroke_width(1)),
                        whisker(lo),
                        whisker(hi),
                    ])?;
                }
                entries.push((f.name.clone(), Some(c)));
            }
            finish(&mut chart, (-0.5, n as f64 - 0.5), level, entries, &side, band)?;
            root.present()?;
            Ok(())
        };
        let _ = draw();
    }
    svg
}
