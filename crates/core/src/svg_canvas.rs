//! The blank SVG page every picture of the crate starts from (map, cells,
//! coverage, histograms) and the text on it: one size, one background, one
//! typeface, one place to change them.

use svg::node::element::{Rectangle, Text};
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

/// Sans-serif text `content` of `size` pixels, anchored (start, baseline) at
/// (`x`, `y`) in page pixels: captions, cell ids, axis labels.
pub fn label(x: f64, y: f64, content: impl Into<String>, size: u32) -> Text {
    Text::new(content)
        .set("x", x)
        .set("y", y)
        .set("font-family", "sans-serif")
        .set("font-size", size)
}

/// A one-line caption under a picture `width` pixels wide, at baseline `y`:
/// [`label`] at `size` pixels, smaller when the line would not fit (a
/// sans-serif glyph is taken as 0.55 of its size wide on average).
pub fn caption(width: f64, y: f64, content: impl Into<String>, size: u32) -> Text {
    let content = content.into();
    let chars = content.chars().count().max(1) as f64;
    let fits = ((width - 16.0) / (0.55 * chars)).floor().max(6.0);
    label(8.0, y, content, size.min(fits as u32))
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

    #[test]
    fn a_long_caption_is_set_smaller_to_fit_its_picture() {
        let short = canvas(900.0, 50.0, "white").add(caption(900.0, 20.0, "room", 14));
        assert!(short.to_string().contains(r#"font-size="14""#));
        let long = "x".repeat(200);
        let doc = canvas(900.0, 50.0, "white").add(caption(900.0, 20.0, long, 14));
        // (900 - 16) / (0.55 * 200) = 8.03: 8 px.
        assert!(doc.to_string().contains(r#"font-size="8""#), "{doc}");
    }

    #[test]
    fn label_is_sans_serif_at_its_place() {
        let doc = canvas(10.0, 10.0, "white").add(label(8.0, 22.5, "cell 3", 14));
        let text = doc.to_string();
        assert!(text.contains("cell 3"), "{text}");
        for attr in [
            r#"x="8""#,
            r#"y="22.5""#,
            r#"font-size="14""#,
            r#"font-family="sans-serif""#,
        ] {
            assert!(text.contains(attr), "{attr} missing: {text}");
        }
    }
}
