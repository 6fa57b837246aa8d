//! The blank SVG page every picture of the crate starts from (map, cells,
//! coverage, histograms): one size, one background, one place to change it.

use svg::node::element::Rectangle;
use svg::Document;

/// A `width` × `height` pixel document (viewBox in the same pixels, origin
/// top-left) filled with the `background` colour.
pub fn canvas(width: f64, height: f64, background: &str) -> Document {
    Document::new()
        .set("viewBox", (0.0, 0.0, width, height))
        .set("width", width)
        .set("height", height)
        .add(
            Rectangle::new()
                .set("width", width)
                .set("height", height)
                .set("fill", background),
        )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn canvas_has_size_viewbox_and_background() {
        let text = canvas(120.0, 80.5, "#f4f4f4").to_string();
        assert!(text.contains(r#"viewBox="0 0 120 80.5""#), "{text}");
        assert!(text.contains(r#"width="120""#) && text.contains(r#"height="80.5""#));
        assert!(text.contains(r##"fill="#f4f4f4""##), "{text}");
    }
}
