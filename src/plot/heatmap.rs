//! `cradle plot FILE.csv --x COL --y COL --z COL --out FILE.png|svg`: a
//! phase diagram. One cell per (x, y) of the sweep grid, coloured by z;
//! log axes where the values are log-spaced; a discrete palette for integer
//! columns with few values (`ejected`, `contacts`), else viridis (log-scaled
//! when z spans more than three decades, as errors do); empty cells grey.
//! For a paper: `--vmin`/`--vmax` fix the colour limits (values beyond take
//! the end colours, so several panels share one scale), `--scale` forces a
//! linear or log colour scale, `--cmap` picks the map (a diverging one for
//! signed columns such as a force minus its preload).

use std::collections::HashMap;
use std::path::Path;

use anyhow::Result;
use plotters::coord::types::RangedCoordf64;
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::colors::colormaps::{BlackWhite, Copper, ViridisRGB};

use super::data::{distinct, log_spaced, Table};
use super::ticks::{number, Ticks};
use super::{drawing, fonts, label, px, unit, FONT};
use crate::error::InputError;

/// Tableau's ten colours: the discrete palette.
const PALETTE: [RGBColor; 10] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
];
const MISSING: RGBColor = RGBColor(215, 215, 215);

pub struct Args {
    pub x: String,
    pub y: String,
    pub z: String,
    /// `COL=VALUE` row filters (a slice of a sweep with more axes).
    pub wheres: Vec<String>,
    pub title: Option<String>,
    /// Colour limits (`--vmin`, `--vmax`); either makes the colours continuous.
    pub vmin: Option<f64>,
    pub vmax: Option<f64>,
    pub scale: Scale,
    pub cmap: Cmap,
    /// Size and resolution (`--size`, `--dpi`).
    pub figure: super::Figure,
}

impl Default for Args {
    fn default() -> Args {
        Args {
            x: String::new(),
            y: String::new(),
            z: String::new(),
            wheres: vec![],
            title: None,
            vmin: None,
            vmax: None,
            scale: Scale::Auto,
            cmap: Cmap::Viridis,
            figure: super::Figure::default(),
        }
    }
}

/// The colour scale of a continuous column (`--scale`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Scale {
    /// Log when the values are positive and span more than three decades.
    Auto,
    Linear,
    Log,
}

impl crate::choice::Choice for Scale {
    const ALL: &'static [Self] = &[Scale::Auto, Scale::Linear, Scale::Log];
    fn name(self) -> &'static str {
        match self {
            Scale::Auto => "auto",
            Scale::Linear => "linear",
            Scale::Log => "log",
        }
    }
}

/// The colour map of a continuous column (`--cmap`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Cmap {
    Viridis,
    /// Black to white (print).
    Gray,
    Copper,
    /// Blue through light grey to red, for signed columns (centre 0 with
    /// symmetric `--vmin`/`--vmax`).
    Coolwarm,
}

impl crate::choice::Choice for Cmap {
    const ALL: &'static [Self] = &[Cmap::Viridis, Cmap::Gray, Cmap::Copper, Cmap::Coolwarm];
    fn name(self) -> &'static str {
        match self {
            Cmap::Viridis => "viridis",
            Cmap::Gray => "gray",
            Cmap::Copper => "copper",
            Cmap::Coolwarm => "coolwarm",
        }
    }
}

impl Cmap {
    /// The colour at h ∈ [0, 1].
    fn at(self, h: f64) -> RGBColor {
        let h = h.clamp(0.0, 1.0);
        match self {
            Cmap::Viridis => ViridisRGB.get_color(h as f32),
            Cmap::Gray => BlackWhite.get_color(h as f32),
            Cmap::Copper => Copper.get_color(h as f32),
            Cmap::Coolwarm => {
                // Moreland's end colours, through light grey.
                let (a, m, b) = (
                    (59.0, 76.0, 192.0),
                    (221.0, 221.0, 221.0),
                    (180.0, 4.0, 38.0),
                );
                let (p, q, t) = if h < 0.5 {
                    (a, m, 2.0 * h)
                } else {
                    (m, b, 2.0 * h - 1.0)
                };
                let mix = |x: f64, y: f64| (x + (y - x) * t).round() as u8;
                RGBColor(mix(p.0, q.0), mix(p.1, q.1), mix(p.2, q.2))
            }
        }
    }
}

/// One axis of the grid.
struct Axis {
    label: String,
    log: bool,
    /// Text values (e.g. `glue`), placed at 0, 1, … in order of appearance.
    cats: Option<Vec<String>>,
    /// Number of values when they are few integers (ticks on each), else 0.
    integers: usize,
    /// Cell edges in plot coordinates (log10 of the value on a log axis).
    edges: Vec<f64>,
    /// A numeric axis's ticks and how they read (SI prefix, ×10ᵏ).
    ticks: Option<Ticks>,
}

impl Axis {
    fn new(col: &str, values: &[f64], cats: Option<Vec<String>>) -> Axis {
        let log = cats.is_none() && log_spaced(values);
        let t: Vec<f64> = values
            .iter()
            .map(|&v| if log { v.log10() } else { v })
            .collect();
        let n = t.len();
        let mut edges = Vec::with_capacity(n + 1);
        if n == 1 {
            let w = if t[0] == 0.0 { 0.5 } else { 0.5 * t[0].abs() };
            edges.extend([t[0] - w, t[0] + w]);
        } else {
            edges.push(t[0] - 0.5 * (t[1] - t[0]));
            for w in t.windows(2) {
                edges.push(0.5 * (w[0] + w[1]));
            }
            edges.push(t[n - 1] + 0.5 * (t[n - 1] - t[n - 2]));
        }
        let mut a = Axis {
            label: label(col),
            log,
            integers: if values.len() <= 20 && values.iter().all(|v| v.fract() == 0.0) {
                values.len()
            } else {
                0
            },
            cats,
            edges,
            ticks: None,
        };
        if a.cats.is_none() {
            let keys = a.key_points();
            let ticks = if log {
                let (lo, hi) = (a.edges[0], a.edges[a.edges.len() - 1]);
                Ticks::log(col, unit(col), keys, (hi - lo).abs())
            } else {
                Ticks::linear(col, unit(col), keys)
            };
            a.label = ticks.label.clone();
            a.ticks = Some(ticks);
        }
        a
    }

    fn format(&self, v: f64) -> String {
        match (&self.cats, &self.ticks) {
            (Some(c), _) if (v - v.round()).abs() < 1e-6 && v >= 0.0 => {
                c.get(v.round() as usize).cloned().unwrap_or_default()
            }
            (_, Some(t)) => t.format(v),
            // A category's neighbourhood (numeric axes all have ticks).
            _ => String::new(),
        }
    }

    /// Where the ticks go (plot coordinates): on a log axis 1, 2 and 5 ×
    /// 10^k within the axis when it spans at most three decades, else powers
    /// of ten (every k-th, at most ~8); elsewhere plotters' own choice for
    /// [`Axis::tick_count`] labels.
    fn key_points(&self) -> Vec<f64> {
        if let Some(t) = &self.ticks {
            return t.at.clone();
        }
        let (a, b) = (self.edges[0], self.edges[self.edges.len() - 1]);
        if !self.log || self.integers > 0 {
            return RangedCoordf64::from(a..b).key_points(self.tick_count());
        }
        log_keys(a.min(b), a.max(b))
    }

    /// Tick labels to ask for: one per category or per integer value.
    fn tick_count(&self) -> usize {
        match &self.cats {
            Some(c) => c.len() + 1,
            None if self.integers > 0 => self.integers + 1,
            None => 10,
        }
    }
}

/// Ticks of a log axis over log10 values `lo..hi`: 1, 2 and 5 × 10^k
/// when it spans at most three decades, else powers of ten (every k-th, at
/// most ~8).
fn log_keys(lo: f64, hi: f64) -> Vec<f64> {
    let mults: &[f64] = if hi - lo <= 3.0 {
        &[1.0, 2.0, 5.0]
    } else {
        &[1.0]
    };
    // Decades with a tick: those of 1, 2, 5 × 10^k, or the powers inside.
    let k0 = if mults.len() > 1 {
        lo.floor()
    } else {
        (lo - 1e-9).ceil()
    } as i32;
    let k1 = (hi + 1e-9).floor() as i32;
    let every = if mults.len() > 1 {
        1
    } else {
        ((k1 - k0 + 1) as usize).div_ceil(8)
    };
    let mut t = vec![];
    for k in (k0..=k1).step_by(every) {
        for m in mults {
            let c = (m * 10f64.powi(k)).log10();
            if c >= lo - 1e-9 && c <= hi + 1e-9 {
                t.push(c);
            }
        }
    }
    t
}

/// A plot coordinate with its ticks at given places (plotters'
/// `WithKeyPoints` has no label formatter for f64).
pub struct Ticked {
    inner: RangedCoordf64,
    keys: Vec<f64>,
}

impl Ticked {
    pub fn new(r: std::ops::Range<f64>, keys: Vec<f64>) -> Ticked {
        Ticked {
            inner: r.into(),
            keys,
        }
    }
}

impl Ranged for Ticked {
    type FormatOption = plotters::coord::ranged1d::DefaultFormatting;
    type ValueType = f64;

    fn map(&self, v: &f64, limit: (i32, i32)) -> i32 {
        self.inner.map(v, limit)
    }

    fn key_points<H: plotters::coord::ranged1d::KeyPointHint>(&self, _: H) -> Vec<f64> {
        self.keys.clone()
    }

    fn range(&self) -> std::ops::Range<f64> {
        self.inner.range()
    }
}

/// A column as coordinates: numbers, or (when any cell is text) the index of
/// each distinct text in order of first appearance.
fn coords(t: &Table, i: usize) -> (Vec<f64>, Option<Vec<String>>) {
    if let Ok(v) = t.numbers(i) {
        return (v, None);
    }
    let mut cats: Vec<String> = vec![];
    let v = t
        .rows
        .iter()
        .map(|r| match cats.iter().position(|c| *c == r[i]) {
            Some(k) => k as f64,
            None => {
                cats.push(r[i].clone());
                (cats.len() - 1) as f64
            }
        })
        .collect();
    (v, Some(cats))
}

enum Colours {
    Discrete(Vec<f64>),
    /// (low, high, log) in colour coordinates, and the map.
    Continuous(f64, f64, bool, Cmap),
}

impl Colours {
    fn of(&self, z: f64) -> RGBColor {
        if !z.is_finite() {
            return MISSING;
        }
        match self {
            Colours::Discrete(vals) => PALETTE[slot(vals, z)],
            Colours::Continuous(lo, hi, log, cmap) => {
                let c = if *log {
                    z.max(f64::MIN_POSITIVE).log10()
                } else {
                    z
                };
                let h = if hi > lo { (c - lo) / (hi - lo) } else { 0.5 };
                cmap.at(h)
            }
        }
    }
}

/// The cells' colours from their finite values `zf` (`uz`: the distinct
/// ones): the discrete palette for a few integers unless a colour flag asks
/// for a scale; else a map between the values' ends or `--vmin`/`--vmax`.
fn colours(a: &Args, zf: &[f64], uz: Vec<f64>) -> Result<Colours, InputError> {
    let asked =
        a.vmin.is_some() || a.vmax.is_some() || a.scale != Scale::Auto || a.cmap != Cmap::Viridis;
    if !asked && !uz.is_empty() && uz.len() <= PALETTE.len() && uz.iter().all(|z| z.fract() == 0.0)
    {
        return Ok(Colours::Discrete(uz));
    }
    let (lo, hi) = zf
        .iter()
        .fold((f64::MAX, f64::MIN), |(l, h), &z| (l.min(z), h.max(z)));
    let (lo, hi) = if zf.is_empty() { (0.0, 1.0) } else { (lo, hi) };
    let (lo, hi) = (a.vmin.unwrap_or(lo), a.vmax.unwrap_or(hi));
    for (name, v) in [("--vmin", a.vmin), ("--vmax", a.vmax)] {
        if let Some(v) = v.filter(|v| !v.is_finite()) {
            return Err(crate::error::flag(name, &v.to_string(), "a finite number"));
        }
    }
    if lo >= hi && (a.vmin.is_some() || a.vmax.is_some()) {
        return Err(crate::error::flag(
            "--vmin",
            &number(lo),
            &format!(
                "below --vmax (or the column's largest value), {}",
                number(hi)
            ),
        ));
    }
    let log = match a.scale {
        Scale::Linear => false,
        Scale::Log => {
            if lo <= 0.0 {
                return Err(crate::error::flag(
                    "--scale",
                    "log",
                    &format!(
                        "a colour range above 0 (its low end is {}: give --vmin > 0, or --scale linear)",
                        number(lo)
                    ),
                ));
            }
            true
        }
        Scale::Auto => lo > 0.0 && hi / lo > 1e3,
    };
    Ok(if log {
        Colours::Continuous(lo.log10(), hi.log10(), true, a.cmap)
    } else {
        Colours::Continuous(lo, hi, false, a.cmap)
    })
}

/// Palette slot of a discrete value: small non-negative integers keep their
/// own colour in every plot (ejected = 1 is always orange), as in the
/// explorer's map; else by rank.
fn slot(vals: &[f64], z: f64) -> usize {
    if vals
        .iter()
        .all(|&v| (0.0..PALETTE.len() as f64).contains(&v))
    {
        z as usize
    } else {
        vals.iter().position(|&v| v == z).unwrap_or(0) % PALETTE.len()
    }
}

pub fn plot(input: &Path, a: &Args, out: &Path) -> Result<()> {
    fonts();
    super::Format::of(out)?;
    let mut t = Table::read(input)?;
    // (after the read: a table that is not there is said so, alone)
    let sidecar = crate::output::sidecar::path(input);
    if !sidecar.exists() {
        eprintln!(
            "cradle: {} has no sidecar ({}): read as a plain table, its rows unchecked",
            input.display(),
            sidecar.display()
        );
    }
    t.filter(&a.wheres)?;
    let (ix, iy, iz) = (
        t.col("--x", &a.x)?,
        t.col("--y", &a.y)?,
        t.col("--z", &a.z)?,
    );
    let ((xs, xcats), (ys, ycats)) = (coords(&t, ix), coords(&t, iy));
    let zs = t.numbers(iz)?;
    if !zs.iter().any(|z| z.is_finite()) {
        // A blank map with a 0–1 colour bar would look like data.
        return Err(InputError::Data {
            path: input.into(),
            what: format!(
                "column `{}` has no value in any row{} (e.g. momentum_error of walled chains): nothing to draw",
                a.z,
                if a.wheres.is_empty() { "" } else { " kept by --where" }
            ),
        }
        .into());
    }
    let (ux, uy) = (distinct(&xs), distinct(&ys));
    for (u, c) in [(&ux, &a.x), (&uy, &a.y)] {
        if u.is_empty() {
            return Err(InputError::Data {
                path: input.into(),
                what: format!("column `{c}` has no numbers"),
            }
            .into());
        }
    }
    // Every (x, y) at most once: otherwise the table is not a grid in x, y.
    let mut cells: HashMap<(usize, usize), f64> = HashMap::new();
    for r in 0..xs.len() {
        if !(xs[r].is_finite() && ys[r].is_finite()) {
            continue;
        }
        let i = ux.partition_point(|&v| v < xs[r]);
        let j = uy.partition_point(|&v| v < ys[r]);
        if cells.insert((i, j), zs[r]).is_some() {
            let axes: Vec<&str> = t
                .header
                .iter()
                .skip(1)
                .take_while(|h| *h != "status")
                .map(String::as_str)
                .filter(|h| *h != a.x && *h != a.y)
                .collect();
            return Err(InputError::Data {
                path: input.into(),
                what: format!(
                    "not a grid in ({}, {}): several rows have {} = {}, {} = {}{}",
                    a.x,
                    a.y,
                    a.x,
                    xs[r],
                    a.y,
                    ys[r],
                    if axes.is_empty() {
                        String::new()
                    } else {
                        format!(
                            "; the table has other axes ({}): pick one value of each with --where COL=VALUE",
                            axes.join(", ")
                        )
                    }
                ),
            }
            .into());
        }
    }
    let (ax, ay) = (Axis::new(&a.x, &ux, xcats), Axis::new(&a.y, &uy, ycats));
    let zf: Vec<f64> = cells.values().copied().filter(|z| z.is_finite()).collect();
    let uz = distinct(&zf);
    let colours = colours(a, &zf, uz)?;
    let title = a.title.clone().unwrap_or_else(|| {
        let sidecar = format!("{}.json", input.display());
        let desc = std::fs::read_to_string(sidecar)
            .ok()
            .and_then(|s| serde_json::from_str::<serde_json::Value>(&s).ok())
            .and_then(|v| v["sweep"]["description"].as_str().map(str::to_string));
        match desc {
            Some(d) => format!("{d}: {}", a.z),
            None => format!(
                "{}: {}",
                input.file_stem().unwrap_or_default().to_string_lossy(),
                a.z
            ),
        }
    });
    let grid = Grid {
        title,
        ax,
        ay,
        cells,
        colours,
        z: a.z.clone(),
        z_label: label(&a.z),
    };
    crate::with_canvas!(out, &a.figure, (9.6, 7.2), |area| draw(area, &grid))
}

struct Grid {
    title: String,
    ax: Axis,
    ay: Axis,
    cells: HashMap<(usize, usize), f64>,
    colours: Colours,
    /// The coloured column.
    z: String,
    z_label: String,
}

fn draw<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, g: &Grid) -> Result<()> {
    area.fill(&WHITE).map_err(drawing)?;
    let w = area.dim_in_pixel().0 as i32;
    let (main, bar) = area.split_horizontally(w - px(170) as i32);
    let (ex, ey) = (&g.ax.edges, &g.ay.edges);
    let mut ch = ChartBuilder::on(&main)
        .caption(&g.title, (FONT, px(20)))
        .margin(px(15))
        .x_label_area_size(px(55))
        .y_label_area_size(px(85))
        .build_cartesian_2d(
            Ticked::new(ex[0]..ex[ex.len() - 1], g.ax.key_points()),
            Ticked::new(ey[0]..ey[ey.len() - 1], g.ay.key_points()),
        )
        .map_err(drawing)?;
    let fx = |v: &f64| g.ax.format(*v);
    let fy = |v: &f64| g.ay.format(*v);
    ch.configure_mesh()
        .disable_mesh()
        .x_desc(&g.ax.label)
        .y_desc(&g.ay.label)
        .x_label_formatter(&fx)
        .y_label_formatter(&fy)
        .x_labels(g.ax.tick_count())
        .y_labels(g.ay.tick_count())
        .label_style((FONT, px(14)))
        .axis_desc_style((FONT, px(16)))
        .draw()
        .map_err(drawing)?;
    let mut rects = Vec::new();
    for i in 0..ex.len() - 1 {
        for j in 0..ey.len() - 1 {
            let z = g.cells.get(&(i, j)).copied().unwrap_or(f64::NAN);
            rects.push(Rectangle::new(
                [(ex[i], ey[j]), (ex[i + 1], ey[j + 1])],
                g.colours.of(z).filled(),
            ));
        }
    }
    ch.draw_series(rects).map_err(drawing)?;
    match &g.colours {
        Colours::Discrete(vals) => {
            // swatches from the top, one per value
            let n = (vals.len() as f64 + 1.0).max(8.0);
            let mut lg = ChartBuilder::on(&bar)
                .caption(&g.z_label, (FONT, px(16)))
                .margin(px(20))
                .margin_top(px(60))
                .build_cartesian_2d(0.0..3.0, -0.5..n - 0.5)
                .map_err(drawing)?;
            let mut keys: Vec<(RGBColor, String)> = vals
                .iter()
                .map(|&v| (PALETTE[slot(vals, v)], number(v)))
                .collect();
            let cells = (ex.len() - 1) * (ey.len() - 1);
            if g.cells.values().filter(|z| z.is_finite()).count() < cells {
                keys.push((MISSING, "no value".into()));
            }
            lg.draw_series(keys.iter().enumerate().map(|(i, (c, _))| {
                let y = n - 1.0 - i as f64;
                Rectangle::new([(0.0, y - 0.4), (0.9, y + 0.4)], c.filled())
            }))
            .map_err(drawing)?;
            lg.draw_series(keys.iter().enumerate().map(|(i, (_, t))| {
                Text::new(
                    t.clone(),
                    (1.2, n - 1.0 - i as f64 + 0.25),
                    (FONT, px(16)).into_font(),
                )
            }))
            .map_err(drawing)?;
        }
        Colours::Continuous(lo, hi, log, _) => {
            let (lo, hi) = if hi > lo {
                (*lo, *hi)
            } else {
                (lo - 0.5, hi + 0.5)
            };
            let ticks = if *log {
                Ticks::log(&g.z, unit(&g.z), log_keys(lo, hi), hi - lo)
            } else {
                Ticks::over(&g.z, unit(&g.z), lo, hi, 10)
            };
            let mut cb = ChartBuilder::on(&bar)
                .margin(px(20))
                .margin_top(px(60))
                .margin_bottom(px(70))
                .y_label_area_size(px(70))
                .build_cartesian_2d(0.0..1.0, Ticked::new(lo..hi, ticks.at.clone()))
                .map_err(drawing)?;
            let fz = |v: &f64| ticks.format(*v);
            cb.configure_mesh()
                .disable_mesh()
                .disable_x_axis()
                .y_desc(&ticks.label)
                .y_label_formatter(&fz)
                .label_style((FONT, px(13)))
                .axis_desc_style((FONT, px(15)))
                .draw()
                .map_err(drawing)?;
            let log = *log;
            colour_strip(&mut cb, (lo, hi), |c| {
                g.colours.of(if log { 10f64.powf(c) } else { c })
            })?;
        }
    }
    Ok(())
}

/// A colour bar's strip: 200 bands from `lo` to `hi` of the bar's value
/// axis, each coloured at its middle.
pub fn colour_strip<DB: DrawingBackend>(
    cb: &mut ChartContext<'_, DB, Cartesian2d<RangedCoordf64, Ticked>>,
    (lo, hi): (f64, f64),
    colour: impl Fn(f64) -> RGBColor,
) -> Result<()> {
    let steps = 200;
    cb.draw_series((0..steps).map(|k| {
        let a = lo + (hi - lo) * k as f64 / steps as f64;
        let b = lo + (hi - lo) * (k + 1) as f64 / steps as f64;
        Rectangle::new([(0.0, a), (1.0, b)], colour(0.5 * (a + b)).filled())
    }))
    .map_err(drawing)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn labels(values: &[f64]) -> Vec<String> {
        let a = Axis::new("x", values, None);
        a.key_points().iter().map(|&c| a.format(c)).collect()
    }

    #[test]
    fn log_axes_tick_at_one_two_five_or_powers_of_ten() {
        let two_decades: Vec<f64> = (0..60)
            .map(|k| 0.0064 * 100f64.powf(k as f64 / 59.0))
            .collect();
        assert_eq!(
            labels(&two_decades),
            ["0.01", "0.02", "0.05", "0.1", "0.2", "0.5"]
        );
        let eight_decades: Vec<f64> = (0..9).map(|k| 10f64.powi(k - 12)).collect();
        assert_eq!(
            labels(&eight_decades),
            ["10⁻¹²", "10⁻¹⁰", "10⁻⁸", "10⁻⁶", "10⁻⁴"]
        );
        // A linear axis keeps plotters' choice.
        let lin: Vec<f64> = (0..40).map(|k| k as f64 * 5e-7).collect();
        assert!(labels(&lin).len() >= 3);
    }
}
