//! SVG charts for the reports, drawn with plotters' SVG backend (no fonts needed: the browser
//! renders the text).

use plotters::prelude::*;

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
    pub title: &'a str,
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
    /// by the set's index; others take the palette's.
    pub dot_colors: Vec<RGBColor>,
    /// Start the y axis at zero (counts and rates, whose small wobbles are not a trend).
    pub y_from_zero: bool,
    /// Fault windows along x (time), shaded; one of no width is a line.
    pub windows: Vec<(f64, f64)>,
    /// Arrows: (from, to, label), e.g. the water current on a map.
    pub arrows: Vec<Arrow>,
}

impl<'a> Chart<'a> {
    pub fn new(title: &'a str, x_label: &'a str, y_label: &'a str) -> Chart<'a> {
        Chart {
            title,
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
        (range(&mut xs_all.into_iter()), range(&mut ys.into_iter()))
    }

    /// The chart as an SVG document of `width` × `height` pixels.
    pub fn svg(&self, width: u32, height: u32) -> String {
        let mut out = String::new();
        let ((mut x0, mut x1), (mut y0, mut y1)) = self.bounds();
        if self.equal_axes {
            // Stretch the narrower axis so that a metre is as long on both.
            let plot = ((width - 90) as f64, (height - 80) as f64);
            let scale = ((x1 - x0) / plot.0).max((y1 - y0) / plot.1);
            let (cx, cy) = (0.5 * (x0 + x1), 0.5 * (y0 + y1));
            (x0, x1, y0, y1) = (
                cx - 0.5 * scale * plot.0,
                cx + 0.5 * scale * plot.0,
                cy - 0.5 * scale * plot.1,
                cy + 0.5 * scale * plot.1,
            );
        }
        {
            let root = SVGBackend::with_string(&mut out, (width, height)).into_drawing_area();
            let _ = self.draw(&root, (x0, x1), (y0, y1));
            let _ = root.present();
        }
        out
    }

    fn draw(
        &self,
        root: &DrawingArea<SVGBackend<'_>, plotters::coord::Shift>,
        x: (f64, f64),
        y: (f64, f64),
    ) -> Result<(), Box<dyn std::error::Error + '_>> {
        root.fill(&WHITE)?;
        let mut chart = ChartBuilder::on(root)
            .caption(self.title, ("sans-serif", 18))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(x.0..x.1, y.0..y.1)?;
        chart
            .configure_mesh()
            .x_desc(self.x_label)
            .y_desc(self.y_label)
            .light_line_style(RGBColor(235, 235, 235))
            .draw()?;
        let shown = self
            .windows
            .iter()
            .filter(|w| w.1 >= x.0 && w.0 <= x.1)
            .map(|w| (w.0.max(x.0), w.1.min(x.1)));
        for (k, (start, end)) in shown.enumerate() {
            let shade = RGBColor(200, 0, 0);
            let drawn = if end - start > 1e-9 {
                chart.draw_series(std::iter::once(Rectangle::new(
                    [(start, y.0), (end, y.1)],
                    shade.mix(0.1).filled(),
                )))?
            } else {
                chart.draw_series(DashedLineSeries::new(
                    vec![(start, y.0), (start, y.1)],
                    4,
                    3,
                    shade.stroke_width(1),
                ))?
            };
            if k == 0 {
                drawn
                    .label("fault window")
                    .legend(move |(a, b)| Rectangle::new([(a, b - 5), (a + 16, b + 5)], shade.mix(0.2).filled()));
            }
        }
        for (from, to, label) in &self.arrows {
            let grey = RGBColor(90, 90, 90);
            let (dx, dy) = (to.0 - from.0, to.1 - from.1);
            // The head: two strokes back from the tip at ±25°, a quarter of the shaft long.
            let head = |turn: f64| {
                let (c, s) = (turn.cos(), turn.sin());
                (to.0 - 0.25 * (c * dx - s * dy), to.1 - 0.25 * (s * dx + c * dy))
            };
            chart.draw_series([
                PathElement::new(vec![*from, *to], grey.stroke_width(2)),
                PathElement::new(vec![head(0.44), *to, head(-0.44)], grey.stroke_width(2)),
            ])?;
            chart.draw_series(std::iter::once(Text::new(label.clone(), *from, ("sans-serif", 12))))?;
        }
        for (k, (name, band)) in self.bands.iter().enumerate() {
            let color = Palette99::pick(k).mix(0.2);
            let mut outline: Vec<(f64, f64)> = band.iter().map(|p| (p.0, p.2)).collect();
            outline.extend(band.iter().rev().map(|p| (p.0, p.1)));
            chart
                .draw_series(std::iter::once(Polygon::new(outline, color.filled())))?
                .label(name.clone());
        }
        for (y, label) in &self.levels {
            let style = ShapeStyle::from(&BLACK).stroke_width(1);
            chart
                .draw_series(DashedLineSeries::new(vec![(x.0, *y), (x.1, *y)], 6, 4, style))?
                .label(label.clone())
                .legend(move |(a, b)| PathElement::new(vec![(a, b), (a + 16, b)], BLACK));
        }
        for (k, s) in self.series.iter().enumerate() {
            let color = Palette99::pick(k).to_rgba();
            // A point without a value (a vehicle lost, then back) breaks the line there.
            let runs: Vec<&[(f64, f64)]> = s
                .points
                .split(|p| !p.1.is_finite())
                .filter(|run| !run.is_empty())
                .collect();
            for (r, run) in runs.iter().enumerate() {
                let drawn = chart.draw_series(LineSeries::new(run.iter().copied(), color.stroke_width(2)))?;
                if r == 0 {
                    drawn
                        .label(s.name.clone())
                        .legend(move |(a, b)| PathElement::new(vec![(a, b), (a + 16, b)], color.stroke_width(2)));
                }
                // A line through one point is drawn as nothing.
                if let [point] = run {
                    chart.draw_series(std::iter::once(Circle::new(*point, 4, color.filled())))?;
                }
            }
        }
        for (k, s) in self.dots.iter().enumerate() {
            let color = self
                .dot_colors
                .get(k)
                .map_or(Palette99::pick(k).to_rgba(), |c| c.to_rgba());
            chart
                .draw_series(s.points.iter().map(|&p| Circle::new(p, 2, color.filled())))?
                .label(s.name.clone())
                .legend(move |(a, b)| Circle::new((a + 8, b), 3, color.filled()));
        }
        for (px, py, text) in &self.labels {
            chart.draw_series(std::iter::once(Circle::new((*px, *py), 2, BLACK.filled())))?;
            chart.draw_series(std::iter::once(Text::new(text.clone(), (*px, *py), ("sans-serif", 11))))?;
        }
        for (px, py, name) in &self.markers {
            chart.draw_series(std::iter::once(Circle::new((*px, *py), 5, BLACK.stroke_width(2))))?;
            chart.draw_series(std::iter::once(Text::new(name.clone(), (*px, *py), ("sans-serif", 12))))?;
        }
        if !self.series.is_empty() || !self.levels.is_empty() || !self.dots.is_empty() || !self.windows.is_empty() {
            chart
                .configure_series_labels()
                .background_style(WHITE.mix(0.8))
                .border_style(BLACK)
                .draw()?;
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

/// Grouped bars: per category, one bar per named value, each category named under its bars.
pub fn bars(
    title: &str,
    x_label: &str,
    y_label: &str,
    categories: &[String],
    groups: &[(&str, Vec<f64>)],
    width: u32,
    height: u32,
) -> String {
    let mut out = String::new();
    {
        let root = SVGBackend::with_string(&mut out, (width, height)).into_drawing_area();
        let top = groups.iter().flat_map(|g| g.1.iter().copied()).fold(1.0f64, f64::max) * 1.1;
        let n = categories.len().max(1);
        let draw = || -> Result<(), Box<dyn std::error::Error + '_>> {
            root.fill(&WHITE)?;
            let mut chart = ChartBuilder::on(&root)
                .caption(title, ("sans-serif", 18))
                .margin(12)
                .x_label_area_size(40)
                .y_label_area_size(60)
                .build_cartesian_2d(-0.5..n as f64 - 0.5, 0.0..top)?;
            // Category c is centred on x = c, where the axis puts a label.
            chart
                .configure_mesh()
                .disable_x_mesh()
                .x_labels(n)
                .x_label_formatter(&|x| category_at(categories, *x))
                .x_desc(x_label)
                .y_desc(y_label)
                .draw()?;
            let w = 0.8 / groups.len().max(1) as f64;
            for (g, (name, values)) in groups.iter().enumerate() {
                let color = Palette99::pick(g).to_rgba();
                chart
                    .draw_series(values.iter().enumerate().map(|(c, v)| {
                        let left = c as f64 - 0.4 + g as f64 * w;
                        Rectangle::new([(left, 0.0), (left + w, *v)], color.filled())
                    }))?
                    .label(*name)
                    .legend(move |(a, b)| Rectangle::new([(a, b - 5), (a + 12, b + 5)], color.filled()));
            }
            chart
                .configure_series_labels()
                .background_style(WHITE.mix(0.8))
                .border_style(BLACK)
                .draw()?;
            root.present()?;
            Ok(())
        };
        let _ = draw();
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_chart_draws_its_lines_labels_and_levels() {
        let mut c = Chart::new("t", "x", "y");
        c.series.push(Series {
            name: "one".into(),
            points: vec![(0.0, 0.0), (1.0, 2.0), (2.0, 1.0)],
        });
        c.levels.push((1.5, "limit".into()));
        c.markers.push((0.0, 0.0, "start".into()));
        let svg = c.svg(400, 300);
        assert!(svg.starts_with("<svg") && svg.contains("</svg>"));
        assert!(svg.contains("<polyline"), "the line");
        // A gap breaks it in two, named once.
        c.series[0].points = vec![(0.0, 0.0), (1.0, 2.0), (2.0, f64::NAN), (3.0, 1.0), (4.0, 0.5)];
        let gapped = c.svg(400, 300);
        let lines = |svg: &str| {
            svg.lines()
                .filter(|l| l.starts_with("<polyline") && l.contains("stroke-width=\"2\""))
                .count()
        };
        // The line and its legend; then two runs and the one legend.
        assert_eq!((lines(&svg), lines(&gapped)), (2, 3), "{gapped}");
        assert_eq!(gapped.matches("\none\n").count(), 1);
        assert!(svg.contains("\none\n") && svg.contains("\nlimit\n") && svg.contains("\nstart\n"));
    }

    #[test]
    fn bars_have_one_rectangle_per_value() {
        for n in [2, 10] {
            let names: Vec<String> = (1..=n).map(|i| format!("{i}→{}", i % n + 1)).collect();
            let values = vec![5.0; n];
            let svg = bars(
                "links",
                "directed link",
                "messages",
                &names,
                &[("delivered", values.clone()), ("dropped", values)],
                400,
                300,
            );
            assert!(svg.matches("<rect").count() >= 2 * n, "{svg}");
            assert!(svg.contains("\ndelivered\n") && svg.contains("directed link"));
            for name in &names {
                assert!(
                    svg.contains(&format!(">\n{name}\n<")),
                    "{name} is under its bars: {svg}"
                );
            }
        }
    }
}
