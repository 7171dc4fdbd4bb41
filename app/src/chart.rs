//! Shared set-up for charts drawn with plotters: the bundled font (DejaVu Sans, free licence in
//! assets/fonts/LICENSE-DejaVu.txt) registered once, so charts render the same on any machine.

use std::sync::Once;

static FONT: &[u8] = include_bytes!("../../assets/fonts/DejaVuSans.ttf");

/// Register the bundled font under the family name "sans-serif". Call before drawing text.
pub fn register_font() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        // The font is bundled and known-good; a failure here would be a build defect.
        let _ = plotters::style::register_font("sans-serif", plotters::style::FontStyle::Normal, FONT);
    });
}
