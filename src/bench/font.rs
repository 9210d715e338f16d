//! The plots' typeface, built into the binary: DejaVu Sans (its Bitstream Vera licence is in
//! `font/LICENSE`). Plotters draws text only in fonts registered with it, so a report's figures
//! need neither system fonts nor fontconfig: headless lab nodes and GPU machines often have
//! neither, and a benchmark that ran for minutes must not fail at its plot.

use std::sync::OnceLock;

/// DejaVu Sans Book, unmodified from Debian's `fonts-dejavu-core`.
static DEJAVU_SANS: &[u8] = include_bytes!("font/DejaVuSans.ttf");

/// The family every plot asks for.
pub const FAMILY: &str = "sans-serif";

/// Registers the built-in typeface as [`FAMILY`] (once per process; later calls return the
/// first call's outcome).
pub fn register() -> Result<(), FontError> {
    static REGISTERED: OnceLock<Result<(), FontError>> = OnceLock::new();
    *REGISTERED.get_or_init(|| {
        plotters::style::register_font(FAMILY, plotters::style::FontStyle::Normal, DEJAVU_SANS)
            .map_err(|_| FontError)
    })
}

/// The built-in typeface did not parse.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error("the built-in font (DejaVu Sans) did not parse")]
pub struct FontError;

#[cfg(test)]
mod tests {
    use plotters::prelude::*;

    /// Text drawn in the registered family puts dark pixels on a white bitmap: the font parses,
    /// and the plots find it by the name they use.
    #[test]
    fn registered_font_draws_text() {
        super::register().unwrap();
        let (w, h) = (120u32, 40u32);
        let mut pixels = vec![255u8; (w * h * 3) as usize];
        {
            let root = BitMapBackend::with_buffer(&mut pixels, (w, h)).into_drawing_area();
            root.draw(&Text::new(
                "raygun 10°",
                (4, 8),
                (super::FAMILY, 20).into_font().color(&BLACK),
            ))
            .unwrap();
            root.present().unwrap();
        }
        let dark = pixels.chunks(3).filter(|p| p[0] < 128).count();
        assert!(dark > 50, "only {dark} dark pixels: no text was drawn");
    }
}
