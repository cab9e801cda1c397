//! `--trace FILE --trace-dt DT`: the trajectory as CSV (`t`, `x_0`.., `v_0`..,
//! SI units), one row every DT of simulated time. States arrive after every
//! step and at both ends of every free flight; rows between two states are
//! interpolated: positions by the cubic Hermite polynomial of the two
//! positions and velocities (exact in free flight, error O(s⁴) over a
//! pendulum's long steps s), velocities linearly.

use std::io::Write;
use std::path::Path;

use crate::engine::granular::{step::State, Beads, Rows};
use crate::engine::{Chain, Observer};

/// Run `write` on a text sink for a trace to `path`, its format by its
/// name: CSV as written, or for `.parquet`/`.pq` the same columns and
/// values in Parquet ([`super::parquet_file::TraceParquet`]).
pub fn in_format<W: Write + Send, T>(
    path: &Path,
    w: W,
    write: impl FnOnce(&mut dyn Write) -> anyhow::Result<T>,
) -> anyhow::Result<T> {
    use anyhow::Context;
    let mut w = w;
    if super::TableKind::from_extension(path) != Some(super::TableKind::Parquet) {
        return write(&mut w);
    }
    let mut p = super::parquet_file::TraceParquet::new(w);
    let r = write(&mut p)?;
    p.close()
        .with_context(|| format!("writing {}", path.display()))?;
    Ok(r)
}

/// The trace row spacing when none is given (s): 400 rows per swing of a
/// pendulum, 20 per contact of a free line.
pub fn default_every(chain: &Chain) -> f64 {
    if chain.is_pendulum() {
        std::f64::consts::TAU / chain.omega() / 400.0
    } else {
        chain.time_scale().map_or(1e-6, |tc| tc / 20.0)
    }
}

pub struct TraceWriter<W: Write> {
    out: W,
    body_of_ball: Vec<usize>,
    every: f64,
    next_row: u64,
    last: Option<(f64, Vec<f64>, Vec<f64>)>,
    last_row_t: f64,
    pub error: Option<std::io::Error>,
}

impl<W: Write> TraceWriter<W> {
    pub fn new(mut out: W, chain: &Chain, every: f64) -> std::io::Result<Self> {
        let n = chain.n_balls;
        let mut h: Vec<String> = vec!["t".into()];
        h.extend((0..n).map(|i| format!("x_{i}")));
        h.extend((0..n).map(|i| format!("v_{i}")));
        writeln!(out, "{}", h.join(","))?;
        Ok(TraceWriter {
            out,
            body_of_ball: chain.body_of_ball.clone(),
            every,
            next_row: 0,
            last: None,
            last_row_t: f64::NEG_INFINITY,
            error: None,
        })
    }

    fn row(&mut self, t: f64, x: &[f64], v: &[f64]) {
        self.last_row_t = t;
        let mut line = format!("{t:e}");
        for &b in &self.body_of_ball {
            line.push_str(&format!(",{:e}", x[b]));
        }
        for &b in &self.body_of_ball {
            line.push_str(&format!(",{:e}", v[b]));
        }
        if let Err(e) = writeln!(self.out, "{line}") {
            self.error.get_or_insert(e);
        }
    }

    /// Write the final state as the last row (unless a row is already there) and flush.
    pub fn finish(mut self) -> std::io::Result<()> {
        if let Some((t, x, v)) = self.last.take() {
            if t > self.last_row_t {
                self.row(t, &x, &v);
            }
        }
        if let Some(e) = self.error.take() {
            return Err(e);
        }
        self.out.flush()
    }
}

impl<W: Write> Observer for TraceWriter<W> {
    fn state(&mut self, t: f64, x: &[f64], v: &[f64]) {
        if let Some((t0, x0, v0)) = self.last.take() {
            loop {
                let ts = self.next_row as f64 * self.every;
                if ts > t {
                    break;
                }
                let dt = t - t0;
                let w = if t > t0 { (ts - t0) / dt } else { 1.0 };
                // Hermite basis on [0, 1].
                let (w2, w3) = (w * w, w * w * w);
                let (h00, h10, h01, h11) = (
                    2.0 * w3 - 3.0 * w2 + 1.0,
                    w3 - 2.0 * w2 + w,
                    -2.0 * w3 + 3.0 * w2,
                    w3 - w2,
                );
                let xi: Vec<f64> = (0..x.len())
                    .map(|i| h00 * x0[i] + h10 * dt * v0[i] + h01 * x[i] + h11 * dt * v[i])
                    .collect();
                let vi: Vec<f64> = v0.iter().zip(v).map(|(a, b)| a + w * (b - a)).collect();
                self.row(ts, &xi, &vi);
                self.next_row += 1;
            }
        } else {
            self.row(t, x, v);
            self.next_row = 1;
        }
        self.last = Some((t, x.to_vec(), v.to_vec()));
    }
}

/// A granular chain's trace (docs/SPEC.md §9): `t`, then `x_i`, `v_i` of
/// the recorded beads, `f_i` (the force of contact i, beads i and i+1) for
/// each recorded bead but the last of the chain, and `f_wall_left`,
/// `f_wall_right` for the walls there are. Rows fall on steps (the step
/// divides the spacing), at t = 0, every, 2·every, … and the end.
pub struct ChainTraceWriter<W: Write> {
    out: W,
    beads: Vec<usize>,
    pub error: Option<std::io::Error>,
}

impl<W: Write> ChainTraceWriter<W> {
    pub fn new(mut out: W, b: &Beads, beads: Vec<usize>) -> std::io::Result<Self> {
        let mut h: Vec<String> = vec!["t".into()];
        h.extend(beads.iter().map(|i| format!("x_{i}")));
        h.extend(beads.iter().map(|i| format!("v_{i}")));
        h.extend(
            beads
                .iter()
                .filter(|&&i| i + 1 < b.n)
                .map(|i| format!("f_{i}")),
        );
        if b.left_wall {
            h.push("f_wall_left".into());
        }
        if b.right_wall {
            h.push("f_wall_right".into());
        }
        writeln!(out, "{}", h.join(","))?;
        Ok(ChainTraceWriter {
            out,
            beads,
            error: None,
        })
    }

    pub fn finish(mut self) -> std::io::Result<()> {
        if let Some(e) = self.error.take() {
            return Err(e);
        }
        self.out.flush()
    }
}

impl<W: Write> Rows for ChainTraceWriter<W> {
    fn row(&mut self, t: f64, b: &Beads, st: &State) {
        if self.error.is_some() {
            return;
        }
        let x = st.positions();
        let mut line = format!("{t:e}");
        for &i in &self.beads {
            line.push_str(&format!(",{:e}", x[i]));
        }
        for &i in &self.beads {
            line.push_str(&format!(",{:e}", st.v[i]));
        }
        for &i in self.beads.iter().filter(|&&i| i + 1 < b.n) {
            line.push_str(&format!(",{:e}", st.force(b, i + 1)));
        }
        if b.left_wall {
            line.push_str(&format!(",{:e}", st.force(b, 0)));
        }
        if b.right_wall {
            line.push_str(&format!(",{:e}", st.force(b, b.n)));
        }
        if let Err(e) = writeln!(self.out, "{line}") {
            self.error = Some(e);
        }
    }
}
