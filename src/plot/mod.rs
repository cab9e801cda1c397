//! Plots of outcome tables and traces (`cradle plot`), drawn with plotters
//! into PNG, SVG or PDF (chosen by the output's extension; PDF is the SVG
//! drawing converted by `svg2pdf`, vector graphics with the font embedded).
//! Text uses the bundled DejaVu Sans (assets/fonts), so plots look the same
//! on every machine. A figure's size is given in inches and its PNG
//! resolution in dots per inch ([`Figure`]), as matplotlib's `figsize` and
//! `dpi`: every font, margin and line scales with the resolution.

pub mod data;
pub mod heatmap;
pub mod spacetime;
pub mod ticks;
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
    Pdf,
}

/// A figure's size (inches; `None`: the plot's own) and PNG resolution
/// (dots per inch; SVG and PDF are vector graphics at 100 units an inch).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Figure {
    pub size: Option<(f64, f64)>,
    pub dpi: f64,
}

impl Default for Figure {
    fn default() -> Figure {
        Figure {
            size: None,
            dpi: 100.0,
        }
    }
}

/// The largest canvas a figure may ask for (pixels a side).
const MAX_SIDE: f64 = 20_000.0;

impl Figure {
    /// The canvas (pixels) of a plot whose own size is `default` inches,
    /// and how many canvas pixels one pixel of the default figure at 100
    /// dpi is: the resolution's ratio, times the figure's linear size
    /// relative to the default when smaller (at most down to 0.7: a
    /// 3.4-inch column figure's tick labels are 7 pt, its title 10 pt).
    pub fn canvas(&self, default: (f64, f64), format: Format) -> ((u32, u32), f64) {
        let (w, h) = self.size.unwrap_or(default);
        let dpi = if format == Format::Png {
            self.dpi
        } else {
            100.0
        };
        let shrink = (w / default.0).min(h / default.1).clamp(0.7, 1.0);
        (
            ((w * dpi).round() as u32, (h * dpi).round() as u32),
            dpi / 100.0 * shrink,
        )
    }

    /// Check `--size` and `--dpi` (a canvas of 16 to 20,000 pixels a side).
    pub fn check(&self) -> Result<(), crate::InputError> {
        if !(self.dpi.is_finite() && (10.0..=1200.0).contains(&self.dpi)) {
            return Err(flag(
                "--dpi",
                &self.dpi.to_string(),
                "10 to 1200 dots per inch",
            ));
        }
        if let Some((w, h)) = self.size {
            let ok = |x: f64| x.is_finite() && x >= 1.0 && x * self.dpi <= MAX_SIDE;
            if !(ok(w) && ok(h)) {
                return Err(flag(
                    "--size",
                    &format!("{w}x{h}"),
                    &format!(
                        "WIDTHxHEIGHT in inches, each at least 1 and at most {} at {} dpi (e.g. 6.4x4.8)",
                        MAX_SIDE / self.dpi,
                        self.dpi
                    ),
                ));
            }
        }
        Ok(())
    }
}

/// Parse `--size WxH` (inches).
pub fn parse_size(s: &str) -> Result<(f64, f64), String> {
    let bad = || format!("`{s}`: WIDTHxHEIGHT in inches, e.g. 6.4x4.8");
    let (w, h) = s.split_once(['x', 'X']).ok_or_else(bad)?;
    let (w, h) = (
        w.trim().parse::<f64>().map_err(|_| bad())?,
        h.trim().parse::<f64>().map_err(|_| bad())?,
    );
    Ok((w, h))
}

thread_local! {
    /// Canvas pixels per pixel at 100 dpi, while a figure is drawn.
    static SCALE: std::cell::Cell<f64> = const { std::cell::Cell::new(1.0) };
}

/// `n` pixels of a figure at 100 dpi in the canvas being drawn.
pub fn px(n: u32) -> u32 {
    SCALE.with(|k| (n as f64 * k.get()).round().max(1.0) as u32)
}

/// Run `draw` with [`px`] scaled by `scale`.
pub fn scaled<T>(scale: f64, draw: impl FnOnce() -> T) -> T {
    let old = SCALE.with(|k| k.replace(scale));
    let r = draw();
    SCALE.with(|k| k.set(old));
    r
}

/// `svg`, a drawing in SVG, as a PDF page of the same size (1 unit =
/// 1/100 inch), text in the bundled font embedded.
pub fn pdf(svg: &str) -> anyhow::Result<Vec<u8>> {
    use svg2pdf::usvg;
    let mut opt = usvg::Options::default();
    let db = opt.fontdb_mut();
    db.load_font_data(FONT_BYTES.to_vec());
    db.set_sans_serif_family("DejaVu Sans");
    let tree = usvg::Tree::from_str(svg, &opt).map_err(|e| anyhow::anyhow!("PDF: {e}"))?;
    let page = svg2pdf::PageOptions { dpi: 100.0 };
    svg2pdf::to_pdf(&tree, svg2pdf::ConversionOptions::default(), page)
        .map_err(|e| anyhow::anyhow!("PDF: {e}"))
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
            Some("pdf") => Ok(Format::Pdf),
            _ => Err(flag(
                "--out",
                &out.display().to_string(),
                "a file ending in .png, .svg or .pdf",
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

/// Make the canvas for `out` (figure `$fig`, of `$inches` unless it says
/// otherwise) and draw on it with `$draw(&area)` (a generic function of the
/// backend), [`px`] scaled to its resolution: PNG through the bitmap
/// backend, SVG as text, PDF as SVG converted ([`pdf`]); drawn into a
/// temporary file beside `out` and published atomically ([`publish`]).
#[macro_export]
macro_rules! with_canvas {
    ($out:expr, $fig:expr, $inches:expr, $draw:expr) => {{
        use plotters::prelude::*;
        let out: &std::path::Path = $out;
        let tmp = $crate::output::guard::with_suffix(out, &$crate::plot::tmp_suffix(out));
        let drawn = (|| -> anyhow::Result<()> {
            let format = $crate::plot::Format::of(out)?;
            let fig: &$crate::plot::Figure = $fig;
            fig.check()?;
            let (size, scale) = fig.canvas($inches, format);
            let writing =
                |e: &dyn std::fmt::Display| anyhow::anyhow!("writing {}: {e}", out.display());
            $crate::plot::scaled(scale, || -> anyhow::Result<()> {
                match format {
                    $crate::plot::Format::Png => {
                        let area = BitMapBackend::new(&tmp, size).into_drawing_area();
                        $draw(&area)?;
                        area.present().map_err(|e| writing(&e))?;
                    }
                    $crate::plot::Format::Svg => {
                        let area = SVGBackend::new(&tmp, size).into_drawing_area();
                        $draw(&area)?;
                        area.present().map_err(|e| writing(&e))?;
                    }
                    $crate::plot::Format::Pdf => {
                        let mut svg = String::new();
                        {
                            let area = SVGBackend::with_string(&mut svg, size).into_drawing_area();
                            $draw(&area)?;
                            area.present().map_err(|e| writing(&e))?;
                        }
                        std::fs::write(&tmp, $crate::plot::pdf(&svg)?).map_err(|e| writing(&e))?;
                    }
                }
                Ok(())
            })
        })();
        $crate::plot::publish(&tmp, out, drawn)
    }};
}

/// A plotters error as an anyhow error.
pub fn drawing<E: std::fmt::Debug>(e: E) -> anyhow::Error {
    anyhow::anyhow!("drawing failed: {e:?}")
}

pub use crate::output::units::{label, unit};
