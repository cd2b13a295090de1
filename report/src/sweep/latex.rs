//! `aggregate.tex`: what aggregate.csv says of each grid point, its means and their 95 %
//! intervals, as a booktabs table a paper can use. `aggregate-table.tex` is the tabular alone, to
//! `\input` in a paper (whose preamble loads booktabs); `aggregate.tex` is a document around it
//! that plain pdflatex compiles as it is.
//!
//! Each cell is aggregate.csv's mean and interval rounded, never computed again: the interval to
//! 2 significant digits, which decides the decimals, and the mean to the same decimals; with one
//! seed (no interval) the mean to 4 significant digits. A metric no run has, or that is 0 in
//! every run (frames lost to noise without a modem), has no column.

use std::fmt::Write as _;
use std::path::Path;

use super::{Stats, SweepSummary, METRICS};
use crate::error::{Context, Result};
use crate::labels;

/// Columns past which aggregate.tex sets the table in `\footnotesize` (8 pt at 10 pt).
const WIDE: usize = 8;

/// The most decimals a cell has, however narrow its interval.
const MAX_DECIMALS: i64 = 6;

/// Writes `aggregate-table.tex` and `aggregate.tex` into `out`.
pub fn write(out: &Path, summary: &SweepSummary) -> Result<()> {
    let columns = columns(summary);
    let table = out.join("aggregate-table.tex");
    std::fs::write(&table, tabular(&columns, summary.points.len()))
        .with_context(|| format!("{}: cannot write the table", table.display()))?;
    let document = out.join("aggregate.tex");
    std::fs::write(&document, self::document(summary, columns.len()))
        .with_context(|| format!("{}: cannot write the table's document", document.display()))?;
    Ok(())
}

/// A column of the table.
struct Column {
    /// Its header's words and unit, as `labels` says them.
    name: String,
    unit: String,
    /// `l` (a swept key's values) or `r` (numbers).
    align: char,
    /// One per grid point, as LaTeX, with its width in em as estimated.
    cells: Vec<(String, f64)>,
}

impl Column {
    fn of(label: labels::Label, align: char, cells: Vec<(String, f64)>) -> Column {
        Column {
            name: label.name.to_string(),
            unit: label.unit.to_string(),
            align,
            cells,
        }
    }

    /// The header: its words on one line if they are no wider than the cells below (as
    /// estimated), else broken into lines about as wide as those cells, in a box aligned as
    /// they are. A unit is never broken.
    fn head(&self) -> String {
        let mut tex = escape(&self.name);
        if !self.unit.is_empty() {
            let _ = write!(tex, " ({})", escape(&self.unit).replace(' ', "~"));
        }
        let words = if self.unit.is_empty() {
            self.name.clone()
        } else {
            format!("{} ({})", self.name, self.unit)
        };
        let cells = self.cells.iter().map(|c| c.1).fold(0.0, f64::max);
        if text_em(&words) <= cells {
            return tex;
        }
        // The longest word (or the unit) fits on a line, with a tenth to spare.
        let mut tokens: Vec<String> = self.name.split_whitespace().map(String::from).collect();
        if !self.unit.is_empty() {
            tokens.push(format!("({})", self.unit));
        }
        let longest = tokens.iter().map(|t| 1.1 * text_em(t)).fold(0.0, f64::max);
        let width = cells.max(longest);
        if text_em(&words) <= width {
            return tex;
        }
        let ragged = if self.align == 'l' {
            "\\raggedright"
        } else {
            "\\raggedleft"
        };
        format!("\\parbox[b]{{{width:.1}em}}{{{ragged} {tex}}}")
    }
}

/// Width in em of text in the roman of the table, as estimated: half an em a character.
fn text_em(text: &str) -> f64 {
    0.5 * text.chars().count() as f64
}

/// Width in em of a cell as `cell` writes it: digits half an em, a point 0.28, a minus sign and
/// ± (with its spaces) more.
fn cell_em(cell: &str) -> f64 {
    if !cell.starts_with('$') {
        return text_em(cell);
    }
    let pm = if cell.contains("\\pm") { 1.222 } else { 0.0 };
    pm + cell
        .replace("\\pm", "")
        .chars()
        .map(|c| match c {
            '0'..='9' => 0.5,
            '.' => 0.278,
            '-' => 0.778,
            _ => 0.0,
        })
        .sum::<f64>()
}

/// The metrics with something to say: a value at some grid point that is not 0 in every run.
fn shown(summary: &SweepSummary) -> Vec<&'static str> {
    METRICS
        .iter()
        .map(|m| m.key)
        .filter(|&key| {
            summary.points.iter().any(|p| {
                p.get(key)
                    .is_some_and(|s| !(s.mean == 0.0 && s.min == 0.0 && s.max == 0.0))
            })
        })
        .collect()
}

/// Every column: the swept keys, the runs, then the metrics shown.
fn columns(summary: &SweepSummary) -> Vec<Column> {
    let points = &summary.points;
    let mut columns: Vec<Column> = summary
        .design
        .grid
        .params
        .iter()
        .enumerate()
        .map(|(i, param)| {
            let cells = points
                .iter()
                .map(|p| {
                    let value = p.values.get(i).map_or("", String::as_str);
                    (escape(value), text_em(value))
                })
                .collect();
            Column::of(labels::key(&param.key), 'l', cells)
        })
        .collect();
    columns.push(Column {
        name: "runs".into(),
        unit: String::new(),
        align: 'r',
        cells: points
            .iter()
            .map(|p| {
                let runs = p.runs.to_string();
                let width = text_em(&runs);
                (runs, width)
            })
            .collect(),
    });
    for key in shown(summary) {
        let cells = points
            .iter()
            .map(|p| {
                let cell = cell(p.get(key));
                let width = cell_em(&cell);
                (cell, width)
            })
            .collect();
        columns.push(Column::of(labels::metric(key), 'r', cells));
    }
    columns
}

/// The tabular: a header row, then a row per grid point, each on a line of its own.
fn tabular(columns: &[Column], points: usize) -> String {
    let mut s = String::new();
    let spec: String = columns.iter().map(|c| c.align).collect();
    let _ = writeln!(s, "\\begin{{tabular}}{{{spec}}}");
    let _ = writeln!(s, "\\toprule");
    let heads: Vec<String> = columns.iter().map(Column::head).collect();
    let _ = writeln!(s, "{} \\\\", heads.join(" & "));
    let _ = writeln!(s, "\\midrule");
    for k in 0..points {
        let cells: Vec<&str> = columns.iter().map(|c| c.cells[k].0.as_str()).collect();
        let _ = writeln!(s, "{} \\\\", cells.join(" & "));
    }
    let _ = writeln!(s, "\\bottomrule");
    let _ = writeln!(s, "\\end{{tabular}}");
    s
}

/// A metric's cell: `$mean \pm ci95$`, the mean alone with one value (`$mean$`), `--` with
/// none.
pub fn cell(stats: Option<Stats>) -> String {
    let Some(s) = stats.filter(|s| s.mean.is_finite()) else {
        return "--".into();
    };
    match s.ci95.filter(|ci| ci.is_finite()) {
        Some(ci) if ci > 0.0 => {
            let d = decimals(ci, 2);
            format!("${} \\pm {}$", fixed(s.mean, d), fixed(ci, d))
        }
        // Seeds that all gave the same value: no interval to set the decimals.
        Some(_) => {
            let d = decimals(s.mean, 4);
            format!("${} \\pm {}$", fixed(s.mean, d), fixed(0.0, d))
        }
        None => format!("${}$", fixed(s.mean, decimals(s.mean, 4))),
    }
}

/// The decimals that write `x` to `digits` significant digits as it rounds (0.0996 to 2 digits
/// is 0.10, not 0.100), from 0 to `MAX_DECIMALS`; 0 for 0.
fn decimals(x: f64, digits: usize) -> usize {
    if x == 0.0 || !x.is_finite() {
        return 0;
    }
    // Rust writes the mantissa rounded, carry included: "1.0e-1".
    let sci = format!("{:.*e}", digits.saturating_sub(1), x.abs());
    let exponent: i64 = sci.split_once('e').and_then(|(_, e)| e.parse().ok()).unwrap_or(0);
    (digits as i64 - 1 - exponent).clamp(0, MAX_DECIMALS) as usize
}

/// `x` with `decimals` decimals, rounded; no sign on a zero.
fn fixed(x: f64, decimals: usize) -> String {
    let s = format!("{x:.decimals$}");
    match s.strip_prefix('-') {
        Some(rest) if rest.chars().all(|c| c == '0' || c == '.') => rest.to_string(),
        _ => s,
    }
}

/// aggregate.tex: the table in a document of its own, with a caption that says what its
/// numbers are.
fn document(summary: &SweepSummary, columns: usize) -> String {
    let grid = &summary.design.grid;
    let keys: Vec<String> = grid
        .params
        .iter()
        .map(|p| format!("\\texttt{{{}}}", escape(&p.key)))
        .collect();
    let seeds = match grid.seeds {
        1 => escape(&format!(
            "the value of its one seed (seed {}), which has no confidence interval",
            grid.seed_start
        )),
        n => escape(&format!(
            "mean ± half the 95 % confidence interval of the mean over {n} seeds (seeds {} to {})",
            grid.seed_start,
            grid.seed_start + n - 1
        )),
    };
    let caption = format!(
        "Sweep of {} over {}. Per grid point, each metric: {seeds}. {} --: no run has a value.",
        escape(&summary.design.mission),
        if keys.is_empty() {
            "its seeds".to_string()
        } else {
            keys.join(" and ")
        },
        escape(
            "Runs: the grid point's runs; a metric is over the runs that have a value of it (the \
             arrival metrics over the runs in which every vehicle arrived). Metrics that are 0 in \
             every run are left out."
        )
    );
    let small = if columns > WIDE {
        "\\footnotesize\n\\setlength{\\tabcolsep}{4pt}\n"
    } else {
        ""
    };
    format!(
        "% A tcpf sweep's aggregate.csv as a table: pdflatex aggregate.tex. aggregate-table.tex is\n\
         % the tabular alone, to \\input in a paper that loads booktabs.\n\
         \\documentclass{{article}}\n\
         \\usepackage{{booktabs}}\n\
         \\usepackage[landscape,margin=1.5cm]{{geometry}}\n\
         \\usepackage[utf8]{{inputenc}}\n\
         \\usepackage[T1]{{fontenc}}\n\
         \\pagestyle{{empty}}\n\
         \\begin{{document}}\n\
         \\begin{{table}}[!htbp]\n\
         \\centering\n\
         \\caption{{{caption}}}\n\
         {small}\\input{{aggregate-table}}\n\
         \\end{{table}}\n\
         \\end{{document}}\n"
    )
}

/// U+0307 COMBINING DOT ABOVE: `β̇` is β and this.
const DOT_ABOVE: char = '\u{307}';

/// `s` as LaTeX text: TeX's special characters escaped, brackets braced (a row that starts with
/// `[` is no argument of the `\\` before it), and the non-ASCII characters of the labels and
/// their like in LaTeX that pdflatex reads with utf8 and T1 (`γ` is `$\gamma$`, `β̇`
/// `$\dot\beta$`); Latin-1 letters as they are. A character with no such LaTeX is written as
/// its code point, `U+2603`.
pub fn escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    let mut chars = s.chars().peekable();
    while let Some(c) = chars.next() {
        if c != DOT_ABOVE && chars.peek() == Some(&DOT_ABOVE) {
            chars.next();
            match math(c) {
                Some(m) if m.len() > 1 && m.starts_with('\\') && m[1..].chars().all(|c| c.is_ascii_alphabetic()) => {
                    let _ = write!(out, "$\\dot{m}$");
                }
                Some(m) => {
                    let _ = write!(out, "$\\dot{{{m}}}$");
                }
                None => {
                    let _ = write!(out, "\\.{{{}}}", escape(&c.to_string()));
                }
            }
            continue;
        }
        match c {
            '\\' => out.push_str("\\textbackslash{}"),
            '&' | '%' | '$' | '#' | '_' | '{' | '}' => {
                out.push('\\');
                out.push(c);
            }
            '~' => out.push_str("\\textasciitilde{}"),
            '^' => out.push_str("\\textasciicircum{}"),
            '[' => out.push_str("{[}"),
            ']' => out.push_str("{]}"),
            '<' => out.push_str("$<$"),
            '>' => out.push_str("$>$"),
            '|' => out.push_str("$|$"),
            // `--` would be a dash.
            '-' if chars.peek() == Some(&'-') => out.push_str("-{}"),
            '\n' | '\r' | '\t' => out.push(' '),
            c if c.is_ascii_control() => {}
            c if c.is_ascii() => out.push(c),
            DOT_ABOVE => out.push_str("\\.{}"),
            c => {
                if let Some(m) = math(c) {
                    let _ = write!(out, "${m}$");
                } else if let Some(t) = text(c) {
                    out.push_str(t);
                } else if ('\u{c0}'..='\u{ff}').contains(&c) {
                    // Latin-1 letters: utf8 and T1 have them.
                    out.push(c);
                } else {
                    let _ = write!(out, "U+{:04X}", c as u32);
                }
            }
        }
    }
    out
}

/// A character's LaTeX in math mode.
fn math(c: char) -> Option<&'static str> {
    Some(match c {
        'α' => "\\alpha",
        'β' => "\\beta",
        'γ' => "\\gamma",
        'δ' => "\\delta",
        'ε' | 'ϵ' => "\\epsilon",
        'ζ' => "\\zeta",
        'η' => "\\eta",
        'θ' => "\\theta",
        'ϑ' => "\\vartheta",
        'ι' => "\\iota",
        'κ' => "\\kappa",
        'λ' => "\\lambda",
        // Greek mu and the micro sign.
        '\u{3bc}' | '\u{b5}' => "\\mu",
        'ν' => "\\nu",
        'ξ' => "\\xi",
        'π' => "\\pi",
        'ρ' => "\\rho",
        'σ' => "\\sigma",
        'ς' => "\\varsigma",
        'τ' => "\\tau",
        'υ' => "\\upsilon",
        'φ' => "\\phi",
        'ϕ' => "\\varphi",
        'χ' => "\\chi",
        'ψ' => "\\psi",
        'ω' => "\\omega",
        'Γ' => "\\Gamma",
        // Greek Delta and the increment sign.
        'Δ' | '∆' => "\\Delta",
        'Θ' => "\\Theta",
        'Λ' => "\\Lambda",
        'Ξ' => "\\Xi",
        'Π' => "\\Pi",
        'Σ' => "\\Sigma",
        'Υ' => "\\Upsilon",
        'Φ' => "\\Phi",
        'Ψ' => "\\Psi",
        // Greek Omega and the ohm sign.
        'Ω' | '\u{2126}' => "\\Omega",
        '⁰' => "^0",
        '¹' => "^1",
        '²' => "^2",
        '³' => "^3",
        '⁴' => "^4",
        '⁵' => "^5",
        '⁶' => "^6",
        '⁷' => "^7",
        '⁸' => "^8",
        '⁹' => "^9",
        '⁻' => "^-",
        '₀' => "_0",
        '₁' => "_1",
        '₂' => "_2",
        '₃' => "_3",
        '°' => "^\\circ",
        '′' => "^\\prime",
        '″' => "^{\\prime\\prime}",
        '∫' => "\\int",
        '∑' => "\\sum",
        '∏' => "\\prod",
        '√' => "\\surd",
        '∂' => "\\partial",
        '∇' => "\\nabla",
        '∞' => "\\infty",
        '−' => "-",
        '±' => "\\pm",
        '∓' => "\\mp",
        '×' => "\\times",
        '·' | '⋅' => "\\cdot",
        '÷' => "\\div",
        '→' => "\\to",
        '←' => "\\leftarrow",
        '↔' => "\\leftrightarrow",
        '⇒' => "\\Rightarrow",
        '≤' => "\\leq",
        '≥' => "\\geq",
        '≠' => "\\neq",
        '≈' => "\\approx",
        '≡' => "\\equiv",
        '∼' => "\\sim",
        '∝' => "\\propto",
        '∈' => "\\in",
        '∀' => "\\forall",
        '∃' => "\\exists",
        '∅' => "\\emptyset",
        '∪' => "\\cup",
        '∩' => "\\cap",
        '⊂' => "\\subset",
        '∧' => "\\wedge",
        '∨' => "\\vee",
        '¬' => "\\neg",
        _ => return None,
    })
}

/// A character's LaTeX in text.
fn text(c: char) -> Option<&'static str> {
    Some(match c {
        '\u{a0}' => "~",
        '\u{2009}' | '\u{202f}' | '\u{2006}' => "\\,",
        '–' => "--",
        '—' => "---",
        '‐' | '‑' => "-",
        '‘' => "`",
        '’' => "'",
        '“' => "``",
        '”' => "''",
        '…' => "\\ldots{}",
        '§' => "\\S{}",
        '¶' => "\\P{}",
        '©' => "\\copyright{}",
        _ => return None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sweep::{Design, Grid, Param, PointSummary};
    use tcpf_core::outputs::summary::Provenance;

    fn stats(mean: f64, ci95: Option<f64>) -> Stats {
        let ci = ci95.unwrap_or(0.0);
        Stats {
            n: if ci95.is_some() { 3 } else { 1 },
            mean,
            std: ci95.map(|c| c / 2.484),
            ci95,
            min: mean - ci,
            max: mean + ci,
        }
    }

    /// A sweep of `comms.edges` over `values`, `seeds` seeds each, with `metric(point, key)`.
    fn summary(values: &[&str], seeds: u64, metric: impl Fn(usize, &str) -> Option<Stats>) -> SweepSummary {
        let design = Design {
            mission: "b-current".into(),
            grid: Grid {
                params: vec![Param {
                    key: "comms.edges".into(),
                    values: values.iter().map(|v| v.to_string()).collect(),
                }],
                seeds,
                seed_start: 1,
            },
            shard: None,
            mode: "in-process".into(),
            clearance: 1.0,
        };
        SweepSummary {
            rerun: design.rerun(),
            planned_runs: design.planned(),
            done_runs: design.planned(),
            interrupted: false,
            failed_runs: Vec::new(),
            gave_up: false,
            points: values
                .iter()
                .enumerate()
                .map(|(k, v)| PointSummary {
                    values: vec![v.to_string()],
                    runs: seeds,
                    arrived: seeds,
                    failed: 0,
                    metrics: METRICS.iter().map(|m| (m.key, metric(k, m.key))).collect(),
                })
                .collect(),
            provenance: Provenance::default(),
            design,
        }
    }

    /// The data rows of a tabular: their cells.
    fn rows(table: &str) -> Vec<Vec<String>> {
        let body = table.split("\\midrule\n").nth(1).unwrap();
        let body = body.split("\\bottomrule").next().unwrap();
        body.lines()
            .map(|l| {
                l.trim()
                    .strip_suffix("\\\\")
                    .unwrap()
                    .split('&')
                    .map(|c| c.trim().to_string())
                    .collect()
            })
            .collect()
    }

    #[test]
    fn a_cell_has_the_decimals_its_interval_allows() {
        let c = |mean, ci| cell(Some(stats(mean, ci)));
        assert_eq!(c(0.3621, Some(0.01234)), "$0.362 \\pm 0.012$");
        assert_eq!(c(55.512345, Some(0.0234)), "$55.512 \\pm 0.023$");
        assert_eq!(c(55.512345, Some(1.26)), "$55.5 \\pm 1.3$");
        assert_eq!(c(55.512345, Some(12.6)), "$56 \\pm 13$");
        // Rounded up to 2 digits, the interval has 2 digits still.
        assert_eq!(c(55.512345, Some(0.0996)), "$55.51 \\pm 0.10$");
        // At least 0 decimals, at most 6.
        assert_eq!(c(55.512345, Some(126.0)), "$56 \\pm 126$");
        assert_eq!(c(55.512345, Some(1e-9)), "$55.512345 \\pm 0.000000$");
        // No interval (one seed): the mean to 4 significant digits.
        assert_eq!(c(55.512345, None), "$55.51$");
        assert_eq!(c(0.000123456, None), "$0.000123$");
        assert_eq!(c(1234.56, None), "$1235$");
        // Seeds that agree: an interval of 0.
        assert_eq!(c(550.0, Some(0.0)), "$550.0 \\pm 0.0$");
        assert_eq!(c(-1e-9, Some(0.5)), "$0.00 \\pm 0.50$", "no sign on a zero");
        assert_eq!(c(-2.25, Some(0.5)), "$-2.25 \\pm 0.50$");
        assert_eq!(cell(None), "--");
    }

    #[test]
    fn the_table_says_words_and_units_and_leaves_out_metrics_with_nothing_to_say() {
        let s = summary(&["[[1,2]]", "[[1,2],[2,3]]"], 3, |k, key| match key {
            "max_coordination_error" => Some(stats([0.3621, 0.5][k], Some(0.01234))),
            "last_arrival" => Some(stats(55.512345, Some([0.0234, 12.6][k]))),
            // No modem: no frame lost to noise, in any run.
            "frames_noise" => Some(stats(0.0, Some(0.0))),
            _ => None,
        });
        let columns = columns(&s);
        let table = tabular(&columns, s.points.len());
        for rule in ["\\toprule", "\\midrule", "\\bottomrule"] {
            assert_eq!(table.matches(rule).count(), 1, "{rule}: {table}");
        }
        assert!(table.starts_with("\\begin{tabular}{lrrr}\n"), "{table}");
        assert!(table.contains("coordination error (s)"), "{table}");
        assert!(table.contains("last arrival (s)"), "{table}");
        assert!(table.contains("communication graph"), "the key's label: {table}");
        assert!(!table.contains("comms.edges"), "{table}");
        assert!(!table.contains("noise") && !table.contains("RMS"), "{table}");
        assert_eq!(
            rows(&table),
            [
                ["{[}{[}1,2{]}{]}", "3", "$0.362 \\pm 0.012$", "$55.512 \\pm 0.023$"],
                ["{[}{[}1,2{]},{[}2,3{]}{]}", "3", "$0.500 \\pm 0.012$", "$56 \\pm 13$"],
            ]
        );

        let dir = std::env::temp_dir().join(format!("tcpf-sweep-latex-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        write(&dir, &s).unwrap();
        assert_eq!(std::fs::read_to_string(dir.join("aggregate-table.tex")).unwrap(), table);
        let document = std::fs::read_to_string(dir.join("aggregate.tex")).unwrap();
        for line in [
            "\\documentclass{article}",
            "\\usepackage{booktabs}",
            "\\usepackage[landscape,margin=1.5cm]{geometry}",
            "\\usepackage[utf8]{inputenc}",
            "\\usepackage[T1]{fontenc}",
            "\\input{aggregate-table}",
        ] {
            assert!(document.lines().any(|l| l == line), "{line}: {document}");
        }
        assert!(
            document
                .contains("mean $\\pm$ half the 95 \\% confidence interval of the mean over 3 seeds (seeds 1 to 3)"),
            "{document}"
        );
        assert!(!document.contains("\\footnotesize") && !document.contains("\\resizebox"));
        assert!(document.is_ascii(), "{document}");
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_wide_table_is_set_smaller_and_one_seed_has_no_interval() {
        // Every metric says something: 1 key, runs and 18 metrics.
        let s = summary(&["ring"], 1, |_, _| Some(stats(1.5, None)));
        let columns = columns(&s);
        assert_eq!(columns.len(), 2 + METRICS.len());
        let table = tabular(&columns, 1);
        assert_eq!(rows(&table)[0][..3], ["ring", "1", "$1.500$"]);
        let document = document(&s, columns.len());
        assert!(document.contains("\\footnotesize\n"), "{document}");
        assert!(document.contains("one seed (seed 1)"), "{document}");
    }

    #[test]
    fn text_is_escaped_and_the_labels_characters_are_latex() {
        assert_eq!(escape("γ messages delivered"), "$\\gamma$ messages delivered");
        assert_eq!(escape("β̇"), "$\\dot\\beta$");
        assert_eq!(escape("dB re 1 µPa²/Hz"), "dB re 1 $\\mu$Pa$^2$/Hz");
        assert_eq!(escape("∫ error"), "$\\int$ error");
        assert_eq!(escape("a − b ± c → d |x|"), "a $-$ b $\\pm$ c $\\to$ d $|$x$|$");
        assert_eq!(
            escape("a_b & 50% $5 #1 {x} ~y^2 \\z"),
            "a\\_b \\& 50\\% \\$5 \\#1 \\{x\\} \\textasciitilde{}y\\textasciicircum{}2 \\textbackslash{}z"
        );
        assert_eq!(escape("[[1,2]]"), "{[}{[}1,2{]}{]}");
        assert_eq!(escape("ring"), "ring");
        assert_eq!(escape("a--b"), "a-{}-b");
        assert_eq!(escape("Müller"), "Müller");
        assert_eq!(escape("☃"), "U+2603");
        // Every label's words in LaTeX of ASCII alone: none left to the fallback.
        for l in labels::KEYS.iter().chain(&METRICS) {
            for s in [l.name, l.short, l.unit] {
                let e = escape(s);
                assert!(e.is_ascii() && !e.contains("U+"), "{s}: {e}");
            }
        }
    }
}
