//! `cradle plot --trace TRACE.csv --out FILE.png|svg`: a space-time diagram
//! of a trace (`cradle run --trace`): each ball's position against time, drawn
//! at its rest slot i·s plus its displacement (s: the largest displacement
//! amplitude, so swings do not overlap), and below it each ball's velocity.

use std::path::Path;

use anyhow::Result;
use plotters::coord::Shift;
use plotters::prelude::*;

use super::data::Table;
use super::heatmap::Ticked;
use super::ticks::{si, Ticks};
use super::{drawing, fonts, px, FONT};
use crate::error::InputError;

/// Most points drawn per line (longer traces are thinned evenly).
const MAX_POINTS: usize = 20_000;

struct Trace {
    title: String,
    t: Vec<f64>,
    x: Vec<Vec<f64>>,
    v: Vec<Vec<f64>>,
    /// Each line's ball (bead) number.
    beads: Vec<usize>,
    spacing: f64,
}

/// The beads of a trace's `prefix` columns (`x_3` → 3), in column order,
/// with their column indices.
fn bead_columns(header: &[String], prefix: &str) -> Vec<(usize, usize)> {
    header
        .iter()
        .enumerate()
        .filter_map(|(c, h)| Some((h.strip_prefix(prefix)?.parse().ok()?, c)))
        .collect()
}

pub fn plot(input: &Path, title: Option<&str>, fig: &super::Figure, out: &Path) -> Result<()> {
    fonts();
    super::Format::of(out)?;
    let table = Table::read_trace(input)?;
    let xs = bead_columns(&table.header, "x_");
    let vs = bead_columns(&table.header, "v_");
    let fs = bead_columns(&table.header, "f_");
    let walls = table
        .header
        .iter()
        .filter(|h| h.starts_with("f_wall_"))
        .count();
    let ascending = xs.windows(2).all(|w| w[0].0 < w[1].0);
    let same_beads = xs.iter().map(|b| b.0).eq(vs.iter().map(|b| b.0));
    if xs.is_empty()
        || table.header[0] != "t"
        || !ascending
        || !same_beads
        || table.header.len() != 1 + xs.len() + vs.len() + fs.len() + walls
    {
        return Err(InputError::Data {
            path: input.into(),
            what: "not a trace: the columns must be t, x_b.., v_b.. (and for a chain f_b.., f_wall_left, f_wall_right; cradle run --trace)".into(),
        }
        .into());
    }
    if table.rows.is_empty() {
        return Err(InputError::Data {
            path: input.into(),
            what: "a trace with no rows".into(),
        }
        .into());
    }
    // The title: the scene's description from the trace's sidecar
    // (`cradle run --trace` writes it), else the file's name.
    let described = std::fs::read_to_string(crate::output::sidecar::path(input))
        .ok()
        .and_then(|t| serde_json::from_str::<serde_json::Value>(&t).ok())
        .and_then(|v| v["description"].as_str().map(str::to_string));
    let name = described.unwrap_or_else(|| {
        input
            .file_stem()
            .unwrap_or_default()
            .to_string_lossy()
            .into_owned()
    });
    let column = |c: usize| table.numbers(c);
    if xs.len() > super::spacetime::LINES_UP_TO {
        // A long chain: every row, as images (no lines to thin).
        let h = super::spacetime::Histories {
            title: title
                .map(str::to_string)
                .unwrap_or_else(|| format!("{name}: {} beads recorded", xs.len())),
            t: column(0)?,
            beads: xs.iter().map(|b| b.0).collect(),
            v: vs.iter().map(|b| column(b.1)).collect::<Result<_, _>>()?,
            f_beads: fs.iter().map(|b| b.0).collect(),
            f: fs.iter().map(|b| column(b.1)).collect::<Result<_, _>>()?,
        };
        return crate::with_canvas!(out, fig, (10.0, 9.0), |area| {
            super::spacetime::draw(area, &h)
        });
    }
    let every = table.rows.len().div_ceil(MAX_POINTS).max(1);
    let keep = |col: Vec<f64>| -> Vec<f64> {
        let last = col.len() - 1;
        col.into_iter()
            .enumerate()
            .filter(|(i, _)| i % every == 0 || *i == last)
            .map(|(_, v)| v)
            .collect()
    };
    let t = keep(column(0)?);
    let mut x = vec![];
    let mut v = vec![];
    for (&(_, xc), &(_, vc)) in xs.iter().zip(&vs) {
        x.push(keep(column(xc)?));
        v.push(keep(column(vc)?));
    }
    let amp = x.iter().flatten().fold(
        0.0f64,
        |m, &a| if a.is_finite() { m.max(a.abs()) } else { m },
    );
    let trace = Trace {
        title: title
            .map(str::to_string)
            .unwrap_or_else(|| format!("{name}: {} balls", xs.len())),
        t,
        x,
        v,
        beads: xs.iter().map(|b| b.0).collect(),
        spacing: if amp > 0.0 { amp } else { 1.0 },
    };
    crate::with_canvas!(out, fig, (10.0, 8.0), |area| draw(area, &trace))
}

fn range(vals: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = vals
        .filter(|v| v.is_finite())
        .fold((f64::MAX, f64::MIN), |(l, h), v| (l.min(v), h.max(v)));
    if lo > hi {
        (0.0, 1.0)
    } else if lo == hi {
        (
            lo - 0.5 * lo.abs().max(1e-12),
            hi + 0.5 * hi.abs().max(1e-12),
        )
    } else {
        let pad = 0.05 * (hi - lo);
        (lo - pad, hi + pad)
    }
}

/// One panel against time: axes t and `y`, quantity `name` in `unit`
/// (both with SI-prefixed ticks; `note` follows the y label).
fn panel<'a, DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    t: std::ops::Range<f64>,
    y: std::ops::Range<f64>,
    (name, unit, note): (&str, &str, &str),
) -> Result<ChartContext<'a, DB, Cartesian2d<Ticked, Ticked>>> {
    let tt = Ticks::over("t", Some("s"), t.start, t.end, 10);
    let ty = Ticks::over(name, Some(unit), y.start, y.end, 10);
    let mut ch = ChartBuilder::on(area)
        .margin(px(12))
        .x_label_area_size(px(45))
        .y_label_area_size(px(85))
        .build_cartesian_2d(Ticked::new(t, tt.at.clone()), Ticked::new(y, ty.at.clone()))
        .map_err(drawing)?;
    ch.configure_mesh()
        .x_desc(&tt.label)
        .y_desc(ty.label.clone() + note)
        .x_label_formatter(&|v| tt.format(*v))
        .y_label_formatter(&|v| ty.format(*v))
        .label_style((FONT, px(13)))
        .axis_desc_style((FONT, px(15)))
        .draw()
        .map_err(drawing)?;
    Ok(ch)
}

fn draw<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, tr: &Trace) -> Result<()> {
    area.fill(&WHITE).map_err(drawing)?;
    let area = area.titled(&tr.title, (FONT, px(20))).map_err(drawing)?;
    let h = area.dim_in_pixel().1 as i32;
    let (top, bottom) = area.split_vertically(h * 3 / 5);
    let (t0, t1) = (tr.t[0], tr.t[tr.t.len() - 1]);
    let colour = |i: usize| Palette99::pick(i).to_rgba();
    let s = tr.spacing;
    let (ylo, yhi) = range(
        tr.x.iter()
            .enumerate()
            .flat_map(|(i, x)| x.iter().map(move |a| i as f64 * s + a)),
    );
    let note = format!(", s = {}", si(s, "m"));
    let mut ch = panel(&top, t0..t1, ylo..yhi, ("position x_i + i·s", "m", &note))?;
    for (i, x) in tr.x.iter().enumerate() {
        let c = colour(i);
        ch.draw_series(LineSeries::new(
            tr.t.iter().zip(x).map(|(&t, &a)| (t, i as f64 * s + a)),
            c.stroke_width(px(2)),
        ))
        .map_err(drawing)?
        .label(format!("ball {}", tr.beads[i]))
        .legend(move |(x, y)| {
            PathElement::new(vec![(x, y), (x + px(18) as i32, y)], c.stroke_width(px(3)))
        });
    }
    ch.configure_series_labels()
        .position(SeriesLabelPosition::UpperLeft)
        .label_font((FONT, px(13)))
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()
        .map_err(drawing)?;
    let (vlo, vhi) = range(tr.v.iter().flatten().copied());
    let mut cv = panel(&bottom, t0..t1, vlo..vhi, ("velocity v_i", "m/s", ""))?;
    for (i, v) in tr.v.iter().enumerate() {
        cv.draw_series(LineSeries::new(
            tr.t.iter().zip(v).map(|(&t, &a)| (t, a)),
            colour(i).stroke_width(px(2)),
        ))
        .map_err(drawing)?;
    }
    Ok(())
}
