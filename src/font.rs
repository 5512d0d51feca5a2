//! The font every plotters figure draws its text with: DejaVu Sans, bundled
//! in the binary (`assets/fonts/DejaVuSans.ttf`, Bitstream Vera licence in
//! `assets/fonts/DejaVuSans-LICENSE.txt`), so the PNG figures of
//! `sagnac report` render the same on a machine with no fonts installed.
//!
//! plotters is built with its `ab_glyph` font backend (no fontconfig): it
//! knows only the fonts registered with it, so text in any figure, SVG or
//! bitmap, needs [`register`] called first (the SVG backend still writes
//! `<text>` elements, but plotters measures labels with the registered font).
//! Every figure module calls it; it is cheap after the first call.

use std::sync::OnceLock;

use plotters::style::FontStyle;

/// The family name figures ask for (plotters' `"sans-serif"`).
pub const FAMILY: &str = "sans-serif";

/// DejaVu Sans 2.37, unmodified.
static DEJAVU_SANS: &[u8] = include_bytes!("../assets/fonts/DejaVuSans.ttf");

/// The bundled font could not be registered (a corrupt font file: a build problem).
#[derive(Debug, Clone, Copy, thiserror::Error)]
#[error("the bundled font DejaVuSans.ttf cannot be parsed")]
pub struct FontError;

/// Register the bundled font as [`FAMILY`] (all styles fall back to it).
/// Idempotent and thread-safe.
pub fn register() -> Result<(), FontError> {
    static DONE: OnceLock<Result<(), FontError>> = OnceLock::new();
    *DONE.get_or_init(|| {
        // plotters falls back to Normal for the other styles (bold, italic)
        plotters::style::register_font(FAMILY, FontStyle::Normal, DEJAVU_SANS)
            .map_err(|_| FontError)
    })
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_bundled_font_registers_and_measures_text() {
        use plotters::style::{IntoFont, TextStyle};
        super::register().unwrap();
        super::register().unwrap();
        let style: TextStyle = (super::FAMILY, 20).into_font().into();
        let (w, h) = style.font.box_size("tau, s").unwrap();
        assert!(w > 20 && h > 5, "{w} x {h}");
    }
}
