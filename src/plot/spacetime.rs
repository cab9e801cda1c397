//! Space-time images of a long chain's trace (`cradle plot --trace` on a
//! trace of more than [`LINES_UP_TO`] beads): bead index against time, one
//! image coloured by velocity (diverging, blue < 0 < red, symmetric about
//! zero) and, when the trace has contact forces, one by the force of
//! contact (b, b+1) (viridis from 0), each with ticks and a colour bar — as
//! the granular-chain papers draw solitary waves.
//!
//! The image is resampled to the plot's pixels (PNG: one cell a pixel; SVG:
//! 4 × 4-pixel cells, so the file stays small): each cell shows the value
//! of largest magnitude among the samples and beads it covers (a wave two
//! beads wide stays visible in a 10^4-bead chain), or the sample nearest its
//! centre if it covers none.

use anyhow::Result;
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::colors::colormaps::ViridisRGB;

use super::heatmap::Ticked;
use super::ticks::Ticks;
use super::{drawing, px, FONT};

/// A trace of at most this many beads is drawn as lines (positions and
/// velocities against time); above, as space-time images.
pub const LINES_UP_TO: usize = 30;

/// Bead histories read from a trace.
pub struct Histories {
    pub title: String,
    /// Row times (s), ascending.
    pub t: Vec<f64>,
    /// The recorded beads, ascending, and each one's velocity per row.
    pub beads: Vec<usize>,
    pub v: Vec<Vec<f64>>,
    /// Beads b whose contact (b, b+1) force is recorded, and its values.
    pub f_beads: Vec<usize>,
    pub f: Vec<Vec<f64>>,
}

/// How a quantity maps to colour.
#[derive(Clone, Copy)]
enum Scale {
    /// Symmetric about zero: blue, white, red over [−m, m].
    Diverging(f64),
    /// Viridis over [lo, hi].
    Sequential(f64, f64),
}

impl Scale {
    fn range(&self) -> (f64, f64) {
        match *self {
            Scale::Diverging(m) => (-m, m),
            Scale::Sequential(lo, hi) => (lo, hi),
        }
    }

    fn of(&self, z: f64) -> RGBColor {
        if !z.is_finite() {
            return RGBColor(200, 200, 200);
        }
        let (lo, hi) = self.range();
        let u = ((z - lo) / (hi - lo)).clamp(0.0, 1.0);
        match self {
            Scale::Sequential(..) => ViridisRGB.get_color(u as f32),
            Scale::Diverging(_) => {
                let mix = |a: (f64, f64, f64), s: f64| {
                    let c = |x: f64| (255.0 + (x - 255.0) * s).round() as u8;
                    RGBColor(c(a.0), c(a.1), c(a.2))
                };
                if u < 0.5 {
                    mix((33.0, 102.0, 172.0), 1.0 - 2.0 * u)
                } else {
                    mix((178.0, 24.0, 43.0), 2.0 * u - 1.0)
                }
            }
        }
    }
}

/// The colour limit of a history: the 95th percentile over samples of
/// each sample's largest finite |value| across beads (1 if none), so that
/// a striker's speed over the first few samples does not wash out the
/// slower wave it launches (the larger values take the end colours).
fn robust(rows: &[Vec<f64>]) -> f64 {
    let n = rows.first().map_or(0, Vec::len);
    let mut m: Vec<f64> = (0..n)
        .map(|k| {
            rows.iter()
                .map(|r| r[k])
                .filter(|x| x.is_finite())
                .fold(0.0f64, |m, x| m.max(x.abs()))
        })
        .filter(|&x| x > 0.0)
        .collect();
    if m.is_empty() {
        return 1.0;
    }
    m.sort_by(f64::total_cmp);
    m[((m.len() - 1) as f64 * 0.95).round() as usize]
}

/// A force history less each contact's force at the first sample (a
/// precompressed chain's static preload), if any is not 0.
fn less_preload(f: &[Vec<f64>]) -> Option<Vec<Vec<f64>>> {
    if f.iter()
        .all(|r| r.first().is_none_or(|x| *x == 0.0 || !x.is_finite()))
    {
        return None;
    }
    Some(
        f.iter()
            .map(|r| {
                let f0 = if r[0].is_finite() { r[0] } else { 0.0 };
                r.iter().map(|x| x - f0).collect()
            })
            .collect(),
    )
}

/// Index of the element of ascending `xs` nearest `x`.
fn nearest(xs: &[f64], x: f64) -> usize {
    let i = xs.partition_point(|&a| a < x);
    if i == 0 {
        0
    } else if i == xs.len() || x - xs[i - 1] <= xs[i] - x {
        i - 1
    } else {
        i
    }
}

/// For each cell of `cell` pixels along a side of `pixels`, the first and
/// last index of ascending `xs` whose values fall in it (`at(u)`: the value
/// at fraction u of the side), or the index nearest its centre if none do.
fn spans(xs: &[f64], pixels: u32, cell: u32, at: impl Fn(f64) -> f64) -> Vec<(usize, usize)> {
    (0..pixels)
        .step_by(cell as usize)
        .map(|p| {
            let u = |q: u32| at(q as f64 / pixels as f64);
            let (a, b) = (u(p), u((p + cell).min(pixels)));
            let (lo, hi) = (a.min(b), a.max(b));
            let first = xs.partition_point(|&x| x < lo);
            let end = xs.partition_point(|&x| x < hi);
            if end > first {
                (first, end - 1)
            } else {
                let k = nearest(xs, at((p as f64 + 0.5 * cell as f64) / pixels as f64));
                (k, k)
            }
        })
        .collect()
}

/// The image's axes: times `t` (a span > 0 even for one row) and the
/// recorded beads ± 1/2.
fn extent(t: &[f64], beads: &[usize]) -> ((f64, f64), (f64, f64)) {
    (
        (t[0], t[t.len() - 1].max(t[0] + f64::MIN_POSITIVE)),
        (beads[0] as f64 - 0.5, beads[beads.len() - 1] as f64 + 0.5),
    )
}

/// The image's cells, top row first (the last bead at the top, time to the
/// right): for a plot of `size` pixels in cells of `cell` pixels, each
/// cell's value of largest magnitude among the samples (`t`, `rows[bead
/// row][sample]`) it covers, the time axis spanning `t` and the bead axis
/// the recorded beads ± 1/2.
pub fn raster(
    t: &[f64],
    beads: &[usize],
    rows: &[Vec<f64>],
    size: (u32, u32),
    cell: u32,
) -> Vec<Vec<f64>> {
    let ((t0, t1), (b0, b1)) = extent(t, beads);
    let bf: Vec<f64> = beads.iter().map(|&b| b as f64).collect();
    let cols = spans(t, size.0, cell, |p| t0 + p * (t1 - t0));
    let lines = spans(&bf, size.1, cell, |p| b1 - p * (b1 - b0));
    lines
        .iter()
        .map(|&(r0, r1)| {
            cols.iter()
                .map(|&(k0, k1)| {
                    let mut z = f64::NAN;
                    for row in &rows[r0..=r1] {
                        for &x in &row[k0..=k1] {
                            // NaN (nothing yet) gives way to any value.
                            if z.is_nan() || x.abs() > z.abs() {
                                z = x;
                            }
                        }
                    }
                    z
                })
                .collect()
        })
        .collect()
}

/// Draw the images: velocity above, force below (if recorded; less its
/// static preload when the chain starts compressed).
pub fn draw<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, h: &Histories) -> Result<()> {
    area.fill(&WHITE).map_err(drawing)?;
    let area = area.titled(&h.title, (FONT, px(20))).map_err(drawing)?;
    let vs = Scale::Diverging(robust(&h.v));
    let v_what = ("velocity v_b", "m/s");
    if h.f_beads.is_empty() {
        return image(&area, h, &h.beads, &h.v, vs, v_what);
    }
    let hgt = area.dim_in_pixel().1 as i32;
    let (top, bottom) = area.split_vertically(hgt / 2);
    image(&top, h, &h.beads, &h.v, vs, v_what)?;
    match less_preload(&h.f) {
        Some(df) => image(
            &bottom,
            h,
            &h.f_beads,
            &df,
            Scale::Diverging(robust(&df)),
            ("force of contact (b, b+1) − at t = 0", "N"),
        ),
        None => image(
            &bottom,
            h,
            &h.f_beads,
            &h.f,
            Scale::Sequential(0.0, robust(&h.f)),
            ("force of contact (b, b+1)", "N"),
        ),
    }
}

/// One image with its axes and colour bar.
fn image<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    h: &Histories,
    beads: &[usize],
    rows: &[Vec<f64>],
    scale: Scale,
    what: (&str, &str),
) -> Result<()> {
    let w = area.dim_in_pixel().0 as i32;
    let (main, bar) = area.split_horizontally(w - px(150) as i32);
    let ((t0, t1), (b0, b1)) = extent(&h.t, beads);
    let tt = Ticks::over("t", Some("s"), t0, t1, 10);
    let mut ch = ChartBuilder::on(&main)
        .margin(px(12))
        .x_label_area_size(px(45))
        .y_label_area_size(px(70))
        .build_cartesian_2d(Ticked::new(t0..t1, tt.at.clone()), b0..b1)
        .map_err(drawing)?;
    ch.configure_mesh()
        .disable_mesh()
        .x_desc(&tt.label)
        .y_desc("bead")
        .x_label_formatter(&|v| tt.format(*v))
        .y_label_formatter(&|v| format!("{:.0}", v))
        .label_style((FONT, px(13)))
        .axis_desc_style((FONT, px(15)))
        .draw()
        .map_err(drawing)?;
    let pa = ch.plotting_area();
    let (pw, ph) = pa.dim_in_pixel();
    let cell: u32 = if std::any::type_name::<DB>().contains("SVG") {
        4
    } else {
        1
    };
    let raw = pa.strip_coord_spec();
    let grid = raster(&h.t, beads, rows, (pw, ph), cell);
    for (cy, line) in grid.iter().enumerate() {
        for (cx, &z) in line.iter().enumerate() {
            let (x, y) = ((cx as u32 * cell) as i32, (cy as u32 * cell) as i32);
            let c = scale.of(z);
            raw.draw(&Rectangle::new(
                [(x, y), (x + cell as i32, y + cell as i32)],
                c.filled(),
            ))
            .map_err(drawing)?;
        }
    }
    colour_bar(&bar, scale, what)
}

fn colour_bar<DB: DrawingBackend>(
    bar: &DrawingArea<DB, Shift>,
    scale: Scale,
    (name, unit): (&str, &str),
) -> Result<()> {
    let (lo, hi) = scale.range();
    let ticks = Ticks::over(name, Some(unit), lo, hi, 10);
    let mut cb = ChartBuilder::on(bar)
        .margin(px(12))
        .margin_bottom(px(57))
        .y_label_area_size(px(75))
        .build_cartesian_2d(0.0..1.0, Ticked::new(lo..hi, ticks.at.clone()))
        .map_err(drawing)?;
    cb.configure_mesh()
        .disable_mesh()
        .disable_x_axis()
        .y_desc(&ticks.label)
        .y_label_formatter(&|v| ticks.format(*v))
        .label_style((FONT, px(12)))
        .axis_desc_style((FONT, px(13)))
        .draw()
        .map_err(drawing)?;
    super::heatmap::colour_strip(&mut cb, (lo, hi), |z| scale.of(z))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_picks_the_closer_neighbour() {
        let xs = [0.0, 1.0, 3.0];
        assert_eq!(nearest(&xs, -1.0), 0);
        assert_eq!(nearest(&xs, 0.4), 0);
        assert_eq!(nearest(&xs, 0.6), 1);
        assert_eq!(nearest(&xs, 2.1), 2);
        assert_eq!(nearest(&xs, 9.0), 2);
    }

    #[test]
    fn a_one_bead_wave_survives_downsampling_at_its_place() {
        // 1,000 beads × 2,000 samples into 100 × 50 cells: a wave one bead
        // wide moving one bead per 2 samples, and one negative sample.
        let t: Vec<f64> = (0..2000).map(|k| k as f64 * 1e-6).collect();
        let beads: Vec<usize> = (0..1000).collect();
        let mut rows = vec![vec![0.0; 2000]; 1000];
        for (k, _) in t.iter().enumerate() {
            rows[k / 2][k] = 1.0;
        }
        rows[900][100] = -2.0;
        let g = raster(&t, &beads, &rows, (100, 50), 1);
        assert_eq!((g.len(), g[0].len()), (50, 100));
        // Every time column holds the wave, in the cell row of its bead.
        for (cx, _) in g[0].iter().enumerate() {
            let at: Vec<usize> = (0..50).filter(|&cy| g[cy][cx] != 0.0).collect();
            let bead = (cx * 20 + 10) / 2; // the bead at the column's centre
            let want = 49 - bead * 50 / 1000; // top row: the last beads
            assert!(
                at.iter().any(|&cy| cy.abs_diff(want) <= 1),
                "column {cx}: {at:?} vs {want}"
            );
        }
        // The single negative sample wins its cell (largest magnitude).
        assert_eq!(g[49 - 900 * 50 / 1000][100 / 20], -2.0);
    }

    #[test]
    fn diverging_scale_is_white_at_zero_and_saturated_at_the_ends() {
        let s = Scale::Diverging(2.0);
        assert_eq!(s.of(0.0), RGBColor(255, 255, 255));
        assert_eq!(s.of(-2.0), RGBColor(33, 102, 172));
        assert_eq!(s.of(5.0), RGBColor(178, 24, 43));
    }

    #[test]
    fn a_striker_does_not_wash_out_the_wave_nor_a_preload_the_force() {
        // 100 samples, 50 beads: a striker at 0.1 m/s over the first 3
        // samples, then a 0.014 m/s wave moving along.
        let mut v = vec![vec![0.0; 100]; 50];
        for k in 0..100 {
            v[(k / 2).min(49)][k] = if k < 3 { 0.1 } else { 0.014 };
        }
        assert_eq!(robust(&v), 0.014);
        assert_eq!(robust(&[vec![0.0; 5]]), 1.0);
        // A 10 N preload under a 0.01 N wave: the wave is what is left.
        let f = vec![vec![10.0, 10.0, 10.01, 10.0], vec![10.0, 10.0, 10.0, 10.01]];
        let df = less_preload(&f).expect("a preload");
        assert!((robust(&df) - 0.01).abs() < 1e-12);
        assert!(less_preload(&[vec![0.0, 1.0]]).is_none());
    }
}
