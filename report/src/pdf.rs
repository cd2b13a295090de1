//! Figures as PDF, for print: the SVG the reports draw, parsed by usvg with its text laid out in
//! DejaVu Sans (which the binary carries: a machine without fonts draws it the same) and turned
//! into outlines, then written as PDF paths. The figures are lines, areas and text in solid
//! colours, which is all this draws.

use std::sync::{Arc, OnceLock};

use pdf_writer::{Content, Finish, Name, Pdf, Rect, Ref};
use usvg::tiny_skia_path::PathSegment;

use crate::error::{bail, failed, Error, Result};

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

/// The drawing of a page, with the opacities it uses (each an ExtGState of the page).
struct Page {
    content: Content,
    alphas: Vec<f32>,
}

impl Page {
    /// The name of the graphics state with `alpha` for fills and strokes.
    fn alpha(&mut self, alpha: f32) -> Vec<u8> {
        let k = match self.alphas.iter().position(|a| *a == alpha) {
            Some(k) => k,
            None => {
                self.alphas.push(alpha);
                self.alphas.len() - 1
            }
        };
        format!("A{k}").into_bytes()
    }

    /// `group`'s drawing, its opacity times `alpha` (what encloses it) applied to each of its
    /// shapes: plotters puts an opacity on single shapes, whose groups overlap nothing.
    fn group(&mut self, group: &usvg::Group, alpha: f32) -> Result<()> {
        let alpha = alpha * group.opacity().get();
        for node in group.children() {
            match node {
                usvg::Node::Group(g) => self.group(g, alpha)?,
                usvg::Node::Path(p) => self.path(p, alpha)?,
                usvg::Node::Text(t) => self.group(t.flattened(), alpha)?,
                usvg::Node::Image(_) => bail!("a figure with an image, which its PDF does not draw"),
            }
        }
        Ok(())
    }

    fn path(&mut self, path: &usvg::Path, alpha: f32) -> Result<()> {
        if !path.is_visible() {
            return Ok(());
        }
        let colour = |paint: &usvg::Paint| match paint {
            usvg::Paint::Color(c) => Ok([c.red, c.green, c.blue].map(|v| f32::from(v) / 255.0)),
            _ => Err(failed!(
                "a figure with a gradient or pattern, which its PDF does not draw"
            )),
        };
        let t = path.abs_transform();
        let c = &mut self.content;
        c.save_state();
        c.transform([t.sx, t.ky, t.kx, t.sy, t.tx, t.ty]);
        let fill = path
            .fill()
            .map(|f| Ok::<_, Error>((colour(f.paint())?, f.opacity().get(), f.rule())));
        let stroke = path
            .stroke()
            .map(|s| Ok::<_, Error>((colour(s.paint())?, s.opacity().get(), s)));
        if let Some(fill) = fill {
            let (rgb, opacity, rule) = fill?;
            let name = self.alpha(alpha * opacity);
            let c = &mut self.content;
            c.set_parameters(Name(&name));
            c.set_fill_rgb(rgb[0], rgb[1], rgb[2]);
            outline(c, path.data());
            match rule {
                usvg::FillRule::NonZero => c.fill_nonzero(),
                usvg::FillRule::EvenOdd => c.fill_even_odd(),
            };
        }
        if let Some(stroke) = stroke {
            let (rgb, opacity, s) = stroke?;
            let name = self.alpha(alpha * opacity);
            let c = &mut self.content;
            c.set_parameters(Name(&name));
            c.set_stroke_rgb(rgb[0], rgb[1], rgb[2]);
            c.set_line_width(s.width().get());
            c.set_line_cap(match s.linecap() {
                usvg::LineCap::Butt => pdf_writer::types::LineCapStyle::ButtCap,
                usvg::LineCap::Round => pdf_writer::types::LineCapStyle::RoundCap,
                usvg::LineCap::Square => pdf_writer::types::LineCapStyle::ProjectingSquareCap,
            });
            c.set_line_join(match s.linejoin() {
                usvg::LineJoin::Round => pdf_writer::types::LineJoinStyle::RoundJoin,
                usvg::LineJoin::Bevel => pdf_writer::types::LineJoinStyle::BevelJoin,
                _ => pdf_writer::types::LineJoinStyle::MiterJoin,
            });
            if let Some(dashes) = s.dasharray() {
                c.set_dash_pattern(dashes.iter().copied(), s.dashoffset());
            }
            outline(c, path.data());
            c.stroke();
        }
        self.content.restore_state();
        Ok(())
    }
}

/// `data` as the current path (quadratic pieces raised to cubic, which PDF has).
fn outline(c: &mut Content, data: &usvg::tiny_skia_path::Path) {
    let mut last = (0.0, 0.0);
    for segment in data.segments() {
        match segment {
            PathSegment::MoveTo(p) => {
                c.move_to(p.x, p.y);
                last = (p.x, p.y);
            }
            PathSegment::LineTo(p) => {
                c.line_to(p.x, p.y);
                last = (p.x, p.y);
            }
            PathSegment::QuadTo(q, p) => {
                let third = |a: f32, b: f32| a + 2.0 / 3.0 * (b - a);
                c.cubic_to(
                    third(last.0, q.x),
                    third(last.1, q.y),
                    third(p.x, q.x),
                    third(p.y, q.y),
                    p.x,
                    p.y,
                );
                last = (p.x, p.y);
            }
            PathSegment::CubicTo(a, b, p) => {
                c.cubic_to(a.x, a.y, b.x, b.y, p.x, p.y);
                last = (p.x, p.y);
            }
            PathSegment::Close => {
                c.close_path();
            }
        }
    }
}

/// `svg` as a one-page PDF of its printed size: a figure that says its width in inches is that
/// wide on the page, and an SVG pixel is a CSS pixel, 3/4 of a point.
pub fn of_svg(svg: &str) -> Result<Vec<u8>> {
    let options = usvg::Options {
        fontdb: fonts(),
        font_family: "DejaVu Sans".into(),
        ..usvg::Options::default()
    };
    let tree = usvg::Tree::from_str(svg, &options).map_err(|e| failed!("a figure's SVG: {e}"))?;
    // usvg gives sizes in CSS pixels, 96 to the inch.
    const POINTS: f32 = 0.75;
    let (w, h) = (tree.size().width() * POINTS, tree.size().height() * POINTS);
    let mut page = Page {
        content: Content::new(),
        alphas: Vec::new(),
    };
    // SVG's y runs down the page, PDF's up it.
    page.content.transform([POINTS, 0.0, 0.0, -POINTS, 0.0, h]);
    page.group(tree.root(), 1.0)?;
    let (catalog, pages, page_id, content_id) = (Ref::new(1), Ref::new(2), Ref::new(3), Ref::new(4));
    let mut pdf = Pdf::new();
    pdf.catalog(catalog).pages(pages);
    pdf.pages(pages).kids([page_id]).count(1);
    let states: Vec<Ref> = (0..page.alphas.len()).map(|k| Ref::new(5 + k as i32)).collect();
    {
        let mut p = pdf.page(page_id);
        p.media_box(Rect::new(0.0, 0.0, w, h))
            .parent(pages)
            .contents(content_id);
        let mut resources = p.resources();
        let mut gs = resources.ext_g_states();
        for (k, id) in states.iter().enumerate() {
            gs.pair(Name(format!("A{k}").as_bytes()), *id);
        }
        gs.finish();
        resources.finish();
        p.finish();
    }
    for (alpha, id) in page.alphas.iter().zip(&states) {
        pdf.ext_graphics(*id).non_stroking_alpha(*alpha).stroking_alpha(*alpha);
    }
    pdf.stream(content_id, &page.content.finish());
    Ok(pdf.finish())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_chart_is_a_pdf_of_its_size_with_its_words_drawn() {
        let mut chart = crate::plots::Chart::new("comms.loss", "max |γi − γj| (s)");
        chart.series.push(crate::plots::Series {
            name: "delay = 1".into(),
            points: vec![(0.0, 0.36), (0.3, 0.58)],
        });
        let size = crate::style::Size::column(0.62);
        let bare = of_svg(&chart.svg(size)).unwrap();
        assert!(bare.starts_with(b"%PDF-"), "a PDF");
        let text = String::from_utf8_lossy(&bare);
        // A column's 3.5 in.
        assert!(text.contains("/MediaBox [0 0 252 "), "{text}");
        // The words are outlines: a longer axis description makes the page's drawing longer by
        // its glyphs.
        let mut described =
            crate::plots::Chart::new("probability that a γ message is lost on its link", "max |γi − γj| (s)");
        described.series = chart.series;
        assert!(of_svg(&described.svg(size)).unwrap().len() > bare.len() + 1000);
    }
}
