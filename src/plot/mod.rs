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

/// Make the canvas for `out` and draw on it with `$draw(&area)` (a generic
/// function of the backend): PNG through the bitmap backend, SVG as text.
#[macro_export]
macro_rules! with_canvas {
    ($out:expr, $size:expr, $draw:expr) => {{
        use plotters::prelude::*;
        match $crate::plot::Format::of($out)? {
            $crate::plot::Format::Png => {
                let area = BitMapBackend::new($out, $size).into_drawing_area();
                $draw(&area)?;
                area.present()
                    .map_err(|e| anyhow::anyhow!("writing {}: {e}", $out.display()))?;
            }
            $crate::plot::Format::Svg => {
                let area = SVGBackend::new($out, $size).into_drawing_area();
                $draw(&area)?;
                area.present()
                    .map_err(|e| anyhow::anyhow!("writing {}: {e}", $out.display()))?;
            }
        }
        anyhow::Ok(())
    }};
}

/// A plotters error as an anyhow error.
pub fn drawing<E: std::fmt::Debug>(e: E) -> anyhow::Error {
    anyhow::anyhow!("drawing failed: {e:?}")
}

/// Physical unit of a column, from its name (docs/SPEC.md §4 keys and outcome columns).
pub fn unit(col: &str) -> Option<&'static str> {
    let base = col.split('[').next().unwrap_or(col);
    let base = base.split('.').next_back().unwrap_or(base);
    Some(match base {
        "gap" | "radius" | "length" | "height" | "max_overlap_m" => "m",
        "mass" => "kg",
        "density" => "kg/m³",
        "young_modulus" => "Pa",
        "velocity" => "m/s",
        "gravity" => "m/s²",
        "duration" | "t_contact" | "t_release" | "dt" | "t" => "s",
        "air_drag" => "1/s",
        _ if base.starts_with("v_") => "m/s",
        _ if base.starts_with("x_") => "m",
        _ => return None,
    })
}

/// An axis or colour-bar label: the column and its unit.
pub fn label(col: &str) -> String {
    match unit(col) {
        Some(u) => format!("{col} ({u})"),
        None => col.to_string(),
    }
}
