//! Figures as PDF, for print: the SVG the reports draw, converted with its text kept as text
//! in DejaVu Sans, which the binary carries (a machine without fonts draws it the same).

use std::sync::{Arc, OnceLock};

use anyhow::{anyhow, Result};

fn fonts() -> Arc<usvg::fontdb::Database> {
    static FONTS: OnceLock<Arc<usvg::fontdb::Database>> = OnceLock::new();
    FONTS
        .get_or_init(|| {
            let mut db = usvg::fontdb::Database::new();
            db.load_font_data(dejavu::sans::regular().to_vec());
            db.load_font_data(dejavu::sans::bold().to_vec());
            db.set_sans_serif_family("DejaVu Sans");
            Arc::new(db)
        })
        .clone()
}

/// `svg` as a one-page PDF of its size.
pub fn of_svg(svg: &str) -> Result<Vec<u8>> {
    let options = usvg::Options {
        fontdb: fonts(),
        font_family: "DejaVu Sans".into(),
        ..usvg::Options::default()
    };
    let tree = usvg::Tree::from_str(svg, &options).map_err(|e| anyhow!("a figure's SVG: {e}"))?;
    svg2pdf::to_pdf(
        &tree,
        svg2pdf::ConversionOptions::default(),
        svg2pdf::PageOptions::default(),
    )
    .map_err(|e| anyhow!("a figure as PDF: {e}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_chart_is_a_pdf_with_its_words_in_it() {
        let mut chart = crate::plots::Chart::new("Coordination error", "comms.loss", "max |γi − γj| (s)");
        chart.series.push(crate::plots::Series {
            name: "delay = 1".into(),
            points: vec![(0.0, 0.36), (0.3, 0.58)],
        });
        let pdf = of_svg(&chart.svg(600, 340)).unwrap();
        assert!(pdf.starts_with(b"%PDF-"), "a PDF");
        // The font is embedded (a subset of DejaVu Sans), not left to the reader's machine.
        let text = String::from_utf8_lossy(&pdf);
        assert!(
            text.contains("DejaVuSans") && text.contains("/FontFile2"),
            "embedded font"
        );
    }
}
