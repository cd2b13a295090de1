//! How every figure looks, in the report and in a sweep: sized in inches for a paper's column
//! with its text in points (never under 8 pt), one colour per meaning from Okabe and Ito's
//! palette (told apart with a colour vision deficiency), and for each family of lines its own
//! marker and dash as well, so that a figure printed in grey still tells them apart. Ticks
//! along one axis share their decimals; legends sit under the data, never over it.

use plotters::coord::ranged1d::Ranged;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;

/// SVG user units per inch: a figure's drawing is this many units per inch of print.
pub const DPI: f64 = 150.0;

/// A paper's column (IEEE, most journals).
pub const COLUMN: f64 = 3.5;
/// Two columns.
pub const DOUBLE_COLUMN: f64 = 7.16;

/// The size of a figure in print: its width, and its height as a share of it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Size {
    /// in.
    pub width: f64,
    pub aspect: f64,
}

impl Size {
    pub fn column(aspect: f64) -> Size {
        Size { width: COLUMN, aspect }
    }

    pub fn with_width(self, width: f64) -> Size {
        Size { width, ..self }
    }

    /// The drawing's size in SVG units.
    pub fn pixels(self) -> (u32, u32) {
        let w = (self.width * DPI).round();
        (w as u32, (w * self.aspect).round() as u32)
    }
}

/// Text sizes, in points of the printed figure.
pub const TICK_PT: f64 = 8.0;
pub const LABEL_PT: f64 = 9.0;
pub const LEGEND_PT: f64 = 8.0;
/// Words written at a point of the data (a vehicle's name at its start).
pub const NOTE_PT: f64 = 8.0;

/// A font of `pt` points in print: plotters writes `font-size` as its size over 1.24, and the
/// SVG is printed at `DPI` units per inch. Rounded up a hundredth, so that the written size
/// is never under `pt`.
pub fn font(pt: f64) -> TextStyle<'static> {
    ("sans-serif", pt / 72.0 * DPI * 1.24 + 0.01).into_font().into()
}

/// `pt` points in SVG units (line widths, marker sizes, gaps).
pub fn units(pt: f64) -> i32 {
    (pt / 72.0 * DPI).round() as i32
}

/// Okabe and Ito's palette.
pub const BLUE: RGBColor = RGBColor(0, 114, 178);
pub const VERMILLION: RGBColor = RGBColor(213, 94, 0);
pub const GREEN: RGBColor = RGBColor(0, 158, 115);
pub const PURPLE: RGBColor = RGBColor(204, 121, 167);
pub const ORANGE: RGBColor = RGBColor(230, 159, 0);
pub const SKY: RGBColor = RGBColor(86, 180, 233);
pub const YELLOW: RGBColor = RGBColor(240, 228, 66);
pub const INK: RGBColor = RGBColor(0, 0, 0);
pub const GREY: RGBColor = RGBColor(86, 86, 86);
pub const LIGHT_GREY: RGBColor = RGBColor(150, 150, 150);

/// What a colour means in a run's report, in every plot that shows it.
pub const DELIVERED: RGBColor = BLUE;
/// A message lost, whatever lost it (where the causes are not told apart).
pub const LOST: RGBColor = GREY;
/// A fault window's shade.
pub const FAULT: RGBColor = YELLOW;

/// The colour of family (or vehicle, or series) `k`.
pub fn family(k: usize) -> RGBColor {
    const FAMILIES: [RGBColor; 7] = [BLUE, VERMILLION, GREEN, PURPLE, ORANGE, SKY, INK];
    FAMILIES[k % FAMILIES.len()]
}

/// A marker's shape: family `k` has its own, eight families (a grid of 2 × 4) before one
/// repeats (with another colour and dash).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Marker {
    Circle,
    Square,
    Triangle,
    Diamond,
    Down,
    Plus,
    Star,
    Cross,
}

impl Marker {
    pub fn of(k: usize) -> Marker {
        const ALL: [Marker; 8] = [
            Marker::Circle,
            Marker::Square,
            Marker::Triangle,
            Marker::Diamond,
            Marker::Down,
            Marker::Plus,
            Marker::Star,
            Marker::Cross,
        ];
        ALL[k % ALL.len()]
    }

    /// Its outline around (0, 0), `r` units from the centre to its edge.
    pub fn outline(self, r: i32) -> Vec<(i32, i32)> {
        let ring = |n: usize, turn: f64, radius: &dyn Fn(usize) -> f64| -> Vec<(i32, i32)> {
            (0..n)
                .map(|i| {
                    let a = turn + std::f64::consts::TAU * i as f64 / n as f64;
                    let rho = radius(i);
                    ((rho * a.cos()).round() as i32, (rho * a.sin()).round() as i32)
                })
                .collect()
        };
        let r = f64::from(r);
        let up = -std::f64::consts::FRAC_PI_2;
        match self {
            Marker::Circle => ring(16, 0.0, &|_| r),
            Marker::Square => ring(4, std::f64::consts::FRAC_PI_4, &|_| r * 1.2),
            Marker::Triangle => ring(3, up, &|_| r * 1.35),
            Marker::Diamond => ring(4, up, &|_| r * 1.35),
            Marker::Down => ring(3, -up, &|_| r * 1.35),
            Marker::Star => ring(10, up, &|i| if i % 2 == 0 { r * 1.5 } else { r * 0.6 }),
            Marker::Plus => plus(r, 0.0),
            Marker::Cross => plus(r, std::f64::consts::FRAC_PI_4),
        }
    }
}

/// A plus of arms `1.3 r` long and `0.9 r` wide, turned by `turn` (a cross at π/4).
fn plus(r: f64, turn: f64) -> Vec<(i32, i32)> {
    let (a, b) = (r * 1.3, r * 0.45);
    [
        (-b, -a),
        (b, -a),
        (b, -b),
        (a, -b),
        (a, b),
        (b, b),
        (b, a),
        (-b, a),
        (-b, b),
        (-a, b),
        (-a, -b),
        (-b, -b),
    ]
    .into_iter()
    .map(|(x, y)| {
        let (sin, cos) = turn.sin_cos();
        ((x * cos - y * sin).round() as i32, (x * sin + y * cos).round() as i32)
    })
    .collect()
}

/// Family `k`'s dash: None for a solid line, else (dash, gap) in units.
pub fn dash(k: usize) -> Option<(i32, i32)> {
    match k % 5 {
        0 => None,
        1 => Some((units(4.0), units(2.0))),
        2 => Some((units(1.2), units(1.6))),
        3 => Some((units(7.0), units(2.0))),
        _ => Some((units(2.5), units(3.5))),
    }
}

/// The ticks plotters draws along `range` for at most `n` labels, and a formatter that writes
/// them all with the decimals the finest of them needs: 55.50, 55.75, 56.00, never 55.5 beside
/// 55.75.
pub fn ticks(range: (f64, f64), n: usize) -> impl Fn(&f64) -> String {
    let points = RangedCoordf64::from(range.0..range.1).key_points(n);
    let decimals = points.iter().map(|v| decimals(*v)).max().unwrap_or(0);
    move |v: &f64| {
        let s = format!("{v:.decimals$}");
        // −0.00 is 0.00.
        if s.trim_start_matches('-').chars().all(|c| c == '0' || c == '.') {
            s.trim_start_matches('-').to_string()
        } else {
            s
        }
    }
}

/// The decimals `v` is written with, up to 6.
fn decimals(v: f64) -> usize {
    (0..=6)
        .find(|&d| {
            let scale = 10f64.powi(d as i32);
            ((v * scale).round() - v * scale).abs() < 1e-6 * scale.max(1.0)
        })
        .unwrap_or(6)
}

/// What a legend entry shows beside its words.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Swatch {
    /// A line in its colour and dash, with its marker if it has one.
    Line {
        colour: RGBColor,
        dash: Option<(i32, i32)>,
        marker: Option<Marker>,
    },
    /// A filled box: a bar, a band or a shaded window (with its opacity).
    Fill { colour: RGBColor, alpha: f64 },
    /// A dot: a set of points.
    Dot { colour: RGBColor },
    /// A line with its marker over a faint box: a family of means with its band.
    Band {
        colour: RGBColor,
        dash: Option<(i32, i32)>,
        marker: Marker,
    },
    /// A bar with its family's marker on it.
    Bar { colour: RGBColor, marker: Marker },
}

impl Swatch {
    /// Family `k`'s line.
    pub fn family(k: usize, marked: bool) -> Swatch {
        Swatch::Line {
            colour: family(k),
            dash: dash(k),
            marker: marked.then(|| Marker::of(k)),
        }
    }
}

type Area<'a> = DrawingArea<SVGBackend<'a>, plotters::coord::Shift>;

/// The height a legend of `entries` takes across `width` units.
pub fn legend_height(entries: &[(String, Swatch)], width: u32) -> u32 {
    if entries.is_empty() {
        return 0;
    }
    let (columns, _) = legend_columns(entries, width);
    let rows = entries.len().div_ceil(columns);
    (rows as i32 * row_height() + units(4.0)) as u32
}

fn row_height() -> i32 {
    units(LEGEND_PT * 1.45)
}

fn swatch_width() -> i32 {
    units(16.0)
}

/// How many columns fit across `width`, and each one's width.
fn legend_columns(entries: &[(String, Swatch)], width: u32) -> (usize, i32) {
    // DejaVu Sans averages about 0.6 em a character.
    let em = LEGEND_PT / 72.0 * DPI;
    let widest = entries
        .iter()
        .map(|(name, _)| (name.chars().count() as f64 * 0.6 * em) as i32)
        .max()
        .unwrap_or(0)
        + swatch_width()
        + units(10.0);
    let columns = ((width as i32 - units(8.0)) / widest.max(1)).clamp(1, 3) as usize;
    (columns.min(entries.len()).max(1), widest)
}

/// The legend, in its own area under the plot: entries in as many columns as fit.
pub fn legend(area: &Area, entries: &[(String, Swatch)]) -> Result<(), Box<dyn std::error::Error>> {
    let (w, _) = area.dim_in_pixel();
    let (columns, column) = legend_columns(entries, w);
    let rows = entries.len().div_ceil(columns);
    let text = font(LEGEND_PT);
    let sw = swatch_width();
    for (i, (name, swatch)) in entries.iter().enumerate() {
        let (c, r) = (i / rows, i % rows);
        let x = units(6.0) + c as i32 * column;
        let y = units(3.0) + r as i32 * row_height() + row_height() / 2;
        let h = units(3.5);
        let mark = |m: Marker, colour: RGBColor| {
            let at = (x + sw / 2, y);
            let outline: Vec<(i32, i32)> = m
                .outline(units(2.2))
                .into_iter()
                .map(|(dx, dy)| (at.0 + dx, at.1 + dy))
                .collect();
            area.draw(&Polygon::new(outline, colour.filled()))
        };
        match *swatch {
            Swatch::Band { colour, dash, marker } => {
                area.draw(&Rectangle::new(
                    [(x, y - h), (x + sw, y + h)],
                    colour.mix(BAND_ALPHA).filled(),
                ))?;
                line(area, (x, x + sw, y), colour, dash)?;
                mark(marker, colour)?;
            }
            Swatch::Bar { colour, marker } => {
                area.draw(&Rectangle::new(
                    [(x, y - h), (x + sw, y + h)],
                    colour.mix(BAR_ALPHA).filled(),
                ))?;
                mark(marker, INK)?;
            }
            Swatch::Line { colour, dash, marker } => {
                line(area, (x, x + sw, y), colour, dash)?;
                if let Some(m) = marker {
                    mark(m, colour)?;
                }
            }
            Swatch::Fill { colour, alpha } => {
                area.draw(&Rectangle::new(
                    [(x, y - h), (x + sw, y + h)],
                    colour.mix(alpha).filled(),
                ))?;
                area.draw(&Rectangle::new([(x, y - h), (x + sw, y + h)], colour.stroke_width(1)))?;
            }
            Swatch::Dot { colour } => {
                area.draw(&Circle::new((x + sw / 2, y), units(2.0), colour.filled()))?;
            }
        }
        area.draw(&Text::new(
            name.clone(),
            (x + sw + units(4.0), y),
            text.clone().pos(plotters::style::text_anchor::Pos::new(
                plotters::style::text_anchor::HPos::Left,
                plotters::style::text_anchor::VPos::Center,
            )),
        ))?;
    }
    Ok(())
}

/// A legend's line from `x0` to `x1` at `y`, in its dash.
fn line(
    area: &Area,
    (x0, x1, y): (i32, i32, i32),
    colour: RGBColor,
    dash: Option<(i32, i32)>,
) -> Result<(), Box<dyn std::error::Error>> {
    let style = colour.stroke_width(line_width());
    match dash {
        None => area.draw(&PathElement::new(vec![(x0, y), (x1, y)], style))?,
        Some((on, off)) => {
            let mut a = x0;
            while a < x1 {
                area.draw(&PathElement::new(vec![(a, y), ((a + on).min(x1), y)], style))?;
                a += on + off;
            }
        }
    }
    Ok(())
}

/// A data line's width: 1 pt.
pub fn line_width() -> u32 {
    units(1.0).max(1) as u32
}

/// How much of its colour a band of a mean takes, and a bar.
pub const BAND_ALPHA: f64 = 0.15;
pub const BAR_ALPHA: f64 = 0.8;

/// `svg` (plotters' drawing of `size`) with its printed size said in inches, so that a browser,
/// a PDF and a paper's `\includegraphics` all draw it at the width it was made for.
pub fn in_inches(svg: String, size: Size) -> String {
    let (w, h) = size.pixels();
    let inches = format!("width=\"{:.3}in\" height=\"{:.3}in\"", size.width, f64::from(h) / DPI);
    svg.replacen(&format!("width=\"{w}\" height=\"{h}\""), &inches, 1)
}

/// The printed size, in points, of every text of `svg` (a figure written by `in_inches`): its
/// font sizes in SVG units scaled by its width in inches over its view box's.
pub fn printed_text_sizes(svg: &str) -> Vec<f64> {
    let attr = |name: &str, from: &str| -> Option<String> {
        let at = from.find(&format!(" {name}=\""))? + name.len() + 3;
        Some(from[at..].split('"').next()?.to_string())
    };
    let Some(head) = svg.find("<svg").map(|at| &svg[at..]) else {
        return Vec::new();
    };
    let head = &head[..head.find('>').unwrap_or(head.len())];
    let inches: Option<f64> = attr("width", head).and_then(|w| w.strip_suffix("in")?.parse().ok());
    let view: Option<f64> = attr("viewBox", head).and_then(|v| v.split_whitespace().nth(2)?.parse().ok());
    // Without inches, a unit is a CSS pixel: 3/4 of a point.
    let scale = match (inches, view) {
        (Some(i), Some(v)) => i * 72.0 / v,
        _ => 0.75,
    };
    svg.split(" font-size=\"")
        .skip(1)
        .filter_map(|rest| rest.split('"').next()?.parse::<f64>().ok())
        .map(|size| size * scale)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_font_of_eight_points_is_written_at_eight_points_or_more() {
        let size = font(8.0).font.get_size();
        // plotters' font-size attribute, at DPI units per inch.
        let written = size / 1.24 / DPI * 72.0;
        assert!((8.0..8.01).contains(&written), "{written}");
    }

    #[test]
    fn ticks_along_an_axis_share_their_decimals() {
        let f = ticks((55.4, 56.1), 6);
        let points = RangedCoordf64::from(55.4..56.1).key_points(6);
        let written: Vec<String> = points.iter().map(&f).collect();
        let decimals: Vec<usize> = written
            .iter()
            .map(|s| s.split('.').nth(1).map_or(0, str::len))
            .collect();
        assert!(decimals.windows(2).all(|w| w[0] == w[1]), "{written:?}");
        let zero = ticks((-1.0, 1.0), 5)(&-0.0);
        assert!(
            zero.starts_with('0') && zero.trim_start_matches(['0', '.']).is_empty(),
            "{zero}"
        );
        assert_eq!(ticks((0.0, 10.0), 5)(&10.0), "10");
    }

    #[test]
    fn families_differ_in_colour_marker_and_dash() {
        for (a, b) in (0..5).flat_map(|a| (0..5).map(move |b| (a, b))).filter(|(a, b)| a < b) {
            assert_ne!(family(a), family(b));
            assert_ne!(Marker::of(a), Marker::of(b));
            assert_ne!(dash(a), dash(b));
        }
        // A 2 × 4 grid: eight families, each its own marker, and none both the colour and the
        // dash of another.
        for (a, b) in (0..8).flat_map(|a| (0..8).map(move |b| (a, b))).filter(|(a, b)| a < b) {
            assert_ne!(Marker::of(a), Marker::of(b));
            assert!(family(a) != family(b) || dash(a) != dash(b), "{a} and {b}");
        }
    }
}
