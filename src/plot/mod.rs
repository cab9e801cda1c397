//! Plots of outcome tables and traces (`cradle plot`), drawn with plotters
//! into PNG or SVG (chosen by the output's extension). Text uses the bundled
//! DejaVu Sans (assets/fonts), so plots look the same on every machine.

pub mod data;
pub mod heatmap;
pub mod spacetime;
pub mod trace;

use std::path::Path;

use plotters::style::FontStyle;

use crate::error::flag;

pub const FONT: &str = "sans-serif";
const FONT_BYTES: &[u8] = include_bytes!("../../assets/fonts/DejaVuSans.ttf");

/// Register the bundled font once.
pub fn fonts() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        for style in [FontStyle::Normal, FontStyle::Bold] {
            let _ = plotters::style::register_font(FONT, style, FONT_BYTES);
        }
    });
}

/// The image formats `--out` may name.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    Png,
    Svg,
}

impl Format {
    pub fn of(out: &Path) -> Result<Format, crate::InputError> {
        match out
            .extension()
            .and_then(|e| e.to_str())
            .map(|e| e.to_ascii_lowercase())
            .as_deref()
        {
            Some("png") => Ok(Format::Png),
            Some("svg") => Ok(Format::Svg),
            _ => Err(flag(
                "--out",
                &out.display().to_string(),
                "a file ending in .png or .svg",
            )),
        }
    }
}

/// Suffix of the temporary image a plot is drawn into before it is
/// published under `--out` (it keeps the image's extension, which the
/// bitmap encoder reads): `x.png` is drawn as `x.png.tmp.png`.
pub fn tmp_suffix(out: &Path) -> String {
    let ext = out
        .extension()
        .map_or(String::new(), |e| e.to_string_lossy().into_owned());
    format!(".tmp.{ext}")
}

/// Make `tmp`, the finished drawing, visible as `out` (synced, then renamed:
/// a kill or a full disk leaves the previous image, never a cut-off one);
/// on error `tmp` is removed.
pub fn publish(tmp: &Path, out: &Path, drawn: anyhow::Result<()>) -> anyhow::Result<()> {
    let r = drawn.and_then(|_| {
        std::fs::File::open(tmp)
            .and_then(|f| f.sync_all())
            .map_err(|e| anyhow::anyhow!("cannot write {}: {e}", tmp.display()))?;
        crate::output::publish::publish(tmp, out)
    });
    if r.is_err() {
        let _ = std::fs::remove_file(tmp);
    }
    r
}

/// Make the canvas for `out` and draw on it with `$draw(&area)` (a generic
/// function of the backend): PNG through the bitmap backend, SVG as text;
/// drawn into a temporary file beside `out` and published atomically
/// ([`publish`]).
#[macro_export]
macro_rules! with_canvas {
    ($out:expr, $size:expr, $draw:expr) => {{
        use plotters::prelude::*;
        let out: &std::path::Path = $out;
        let tmp = $crate::output::guard::with_suffix(out, &$crate::plot::tmp_suffix(out));
        let drawn = (|| -> anyhow::Result<()> {
            match $crate::plot::Format::of(out)? {
                $crate::plot::Format::Png => {
                    let area = BitMapBackend::new(&tmp, $size).into_drawing_area();
                    $draw(&area)?;
                    area.present()
                        .map_err(|e| anyhow::anyhow!("writing {}: {e}", out.display()))?;
                }
                $crate::plot::Format::Svg => {
                    let area = SVGBackend::new(&tmp, $size).into_drawing_area();
                    $draw(&area)?;
                    area.present()
                        .map_err(|e| anyhow::anyhow!("writing {}: {e}", out.display()))?;
                }
            }
            Ok(())
        })();
        $crate::plot::publish(&tmp, out, drawn)
    }};
}

/// A plotters error as an anyhow error.
pub fn drawing<E: std::fmt::Debug>(e: E) -> anyhow::Error {
    anyhow::anyhow!("drawing failed: {e:?}")
}

pub use crate::output::units::{label, unit};
