//! What one scene sends to the device and gets back: its header, its
//! parameters (`layout::PARAMS`), the state it starts from
//! (`layout::STATE`), and the [`Run`] read from its final state. Every
//! value is placed and read **by name** through the layout table, never by
//! position: reordering the table moves the host's values and the shader's
//! offsets (the generated prelude) together. The test below packs with a
//! reordered table and reads every field back by name. Names are resolved
//! to places once per scene shape ([`Placement`]), and a batch's scenes are
//! packed in parallel straight into its buffers ([`batch`]).

use rayon::prelude::*;

use crate::backend::layout::cradle::{self as layout, Field, GpuHeader, PARAMS, STATE, WORDS};
use crate::backend::layout::cradle::{FLAG_DAMPED, FLAG_DRAG, FLAG_EXACT, FLAG_PENDULUM};
use crate::engine::cradle::{closing_speed_floor, kick_weights, Run};
use crate::engine::real::Real;
use crate::engine::{plan, row_dt, Chain, Limits, Solver, StepPlan, UNSTEPPED};

/// A batch's scenes planned and packed ([`batch`]): a header and a `dt`
/// column each ([`crate::engine::row_dt`] of the plan it runs with), and
/// the parameter and state buffers.
pub(super) struct Batch<R> {
    pub headers: Vec<GpuHeader>,
    pub dts: Vec<f64>,
    pub params: Vec<R>,
    pub state: Vec<R>,
}

/// Plan and pack `jobs`: planned in order (each scene's regions start where
/// the one before it ends; a [`Placement`] per shape, resolved once), then
/// packed in parallel, straight into the batch's buffers, on the current
/// rayon pool (the GPU backend's own, `Gpu::host`).
pub(super) fn batch<R: Real>(jobs: &[(&Chain, &Solver)]) -> Batch<R> {
    type Shape = ((usize, usize), Placement<'static>, Placement<'static>);
    let mut shapes: Vec<Shape> = Vec::new();
    let mut plans = Vec::with_capacity(jobs.len());
    let mut headers = Vec::with_capacity(jobs.len());
    let mut dts = Vec::with_capacity(jobs.len());
    let (mut np, mut ns) = (0, 0);
    for (ch, solver) in jobs {
        let (sp, lim) = plan(ch, solver);
        let sp = sp.unwrap_or(UNSTEPPED);
        let key = (ch.n_bodies(), sp.weights.len());
        let k = match shapes.iter().position(|s| s.0 == key) {
            Some(k) => k,
            None => {
                let (nb, nw) = key;
                let (p, s) = (
                    Placement::new(PARAMS, nb, nw),
                    Placement::new(STATE, nb, nw),
                );
                shapes.push((key, p, s));
                shapes.len() - 1
            }
        };
        dts.push(row_dt(&sp));
        headers.push(header(ch, &sp, &lim, np, ns));
        np += shapes[k].1.len();
        ns += shapes[k].2.len();
        plans.push((sp, lim, k));
    }
    let (mut p_buf, mut s_buf) = (vec![R::zero(); np], vec![R::zero(); ns]);
    let mut regions = Vec::with_capacity(jobs.len());
    let (mut p_rest, mut s_rest) = (&mut p_buf[..], &mut s_buf[..]);
    for (_, _, k) in &plans {
        let (p, pr) = std::mem::take(&mut p_rest).split_at_mut(shapes[*k].1.len());
        let (s, sr) = std::mem::take(&mut s_rest).split_at_mut(shapes[*k].2.len());
        (p_rest, s_rest) = (pr, sr);
        regions.push((p, s));
    }
    regions
        .into_par_iter()
        .zip(plans.par_iter())
        .zip(jobs.par_iter())
        .with_min_len(256)
        .for_each(|(((p, s), (sp, lim, k)), (ch, _))| {
            params(&shapes[*k].1, p, ch, sp, lim);
            state(&shapes[*k].2, s, ch);
        });
    Batch {
        headers,
        dts,
        params: p_buf,
        state: s_buf,
    }
}

/// Where each field of a layout table lies in the region of a scene of one
/// shape (`nb` bodies, `nw` substep weights): resolved once per shape, so
/// that packing a scene looks up no offset.
pub(super) struct Placement<'t> {
    fields: &'t [Field],
    ranges: Vec<std::ops::Range<usize>>,
    len: usize,
}

impl<'t> Placement<'t> {
    pub(super) fn new(fields: &'t [Field], nb: usize, nw: usize) -> Self {
        assert!(fields.len() <= 64, "a layout table of at most 64 fields");
        let ranges = fields
            .iter()
            .map(|(name, _)| layout::range(fields, name, nb, nw))
            .collect();
        Placement {
            fields,
            ranges,
            len: layout::len(fields, nb, nw),
        }
    }

    /// The region's length.
    pub(super) fn len(&self) -> usize {
        self.len
    }
}

/// A scene's region of a per-scene buffer, filled field by field by name
/// where its [`Placement`] says; [`Region::finish`] checks that every
/// field of the table was set once.
struct Region<'p, 'o, R> {
    place: &'p Placement<'p>,
    out: &'o mut [R],
    /// Bit k: field k is set.
    set: u64,
    /// The field after the last one set: the packers set them mostly in
    /// the table's order, so a name is usually found at the first look.
    next: usize,
}

impl<'p, 'o, R: Real> Region<'p, 'o, R> {
    fn new(place: &'p Placement<'p>, out: &'o mut [R]) -> Self {
        assert_eq!(out.len(), place.len, "a region as long as its placement");
        Region {
            place,
            out,
            set: 0,
            next: 0,
        }
    }

    /// The index of field `name` in the table.
    fn index(&self, name: &str) -> usize {
        let fields = self.place.fields;
        match fields.get(self.next) {
            Some(f) if f.0 == name => self.next,
            _ => fields
                .iter()
                .position(|f| f.0 == name)
                .unwrap_or_else(|| panic!("no field {name} in the GPU layout")),
        }
    }

    /// Field `k` (`name`) is set now, once: the next look starts after it.
    fn claim(&mut self, k: usize, name: &str) {
        assert!(
            self.set & (1 << k) == 0,
            "GPU layout field {name} packed twice"
        );
        self.set |= 1 << k;
        self.next = k + 1;
    }

    /// Field `name` gets `values` (exactly as many as the table says).
    fn put(&mut self, name: &str, values: impl IntoIterator<Item = R>) {
        let k = self.index(name);
        let range = self.place.ranges[k].clone();
        let want = range.len();
        let mut n = 0;
        for (slot, v) in self.out[range].iter_mut().zip(values) {
            *slot = v;
            n += 1;
        }
        assert_eq!(n, want, "GPU layout field {name}: values packed");
        self.claim(k, name);
    }

    /// Every value of field `name` is `x`.
    fn fill(&mut self, name: &str, x: R) {
        let k = self.index(name);
        self.out[self.place.ranges[k].clone()].fill(x);
        self.claim(k, name);
    }

    /// Field `name` gets `values` (f64, rounded to the precision).
    fn put64(&mut self, name: &str, values: impl IntoIterator<Item = f64>) {
        self.put(name, values.into_iter().map(R::of));
    }

    /// Fields `a` and `b` get the firsts and the seconds of `pairs` (f64,
    /// rounded to the precision): what is computed in pairs, once.
    fn put64_pairs(&mut self, a: &str, b: &str, pairs: impl IntoIterator<Item = (f64, f64)>) {
        let (ka, kb) = (self.index(a), self.index(b));
        let (ra, rb) = (self.place.ranges[ka].clone(), self.place.ranges[kb].clone());
        assert_eq!(ra.len(), rb.len(), "GPU layout fields {a} and {b}: lengths");
        let mut n = 0;
        for (i, (x, y)) in pairs.into_iter().take(ra.len()).enumerate() {
            self.out[ra.start + i] = R::of(x);
            self.out[rb.start + i] = R::of(y);
            n += 1;
        }
        assert_eq!(n, ra.len(), "GPU layout fields {a} and {b}: values packed");
        self.claim(ka, a);
        self.claim(kb, b);
    }

    fn finish(self) {
        let fields = self.place.fields;
        if let Some(k) = (0..fields.len()).find(|k| self.set & (1 << k) == 0) {
            panic!("GPU layout field {} not packed", fields[k].0);
        }
    }
}

/// The header of a scene whose parameters start at `input` and whose state
/// at `output`.
pub(super) fn header(
    ch: &Chain,
    sp: &StepPlan,
    lim: &Limits,
    input: usize,
    output: usize,
) -> GpuHeader {
    GpuHeader {
        nb: ch.n_bodies() as u32,
        input: input as u32,
        output: output as u32,
        max_steps: lim.max_steps.min(u32::MAX as u64) as u32,
        n_weights: sp.weights.len() as u32,
        quarters: if sp.graded { sp.grade_quarters } else { 0 },
        flags: [
            (ch.is_pendulum(), FLAG_PENDULUM),
            (ch.damping_a > 0.0, FLAG_DAMPED),
            (ch.air_drag > 0.0, FLAG_DRAG),
            (sp.exact, FLAG_EXACT),
        ]
        .iter()
        .filter(|(on, _)| *on)
        .fold(0, |a, (_, f)| a | f),
    }
}

/// A scene's parameters into `out`, laid out as `place` (of
/// `layout::PARAMS` for the scene's shape) says.
pub(super) fn params<R: Real>(
    place: &Placement,
    out: &mut [R],
    ch: &Chain,
    sp: &StepPlan,
    lim: &Limits,
) {
    let nb = ch.n_bodies();
    let mut r = Region::new(place, out);
    r.put64("h", [sp.h]);
    r.put(
        "v_floor",
        [closing_speed_floor::<R>(ch.v_in(), sp.settle_rel)],
    );
    r.put64("max_time", [lim.max_time]);
    // `one`: keeps the compensated sums from being optimised away
    r.put("one", [R::one()]);
    r.put64("h_min", [sp.h_min]);
    r.put64("t_scale", [sp.t_scale]);
    r.put64("h_free", [sp.h_free]);
    r.put64("g", [ch.gravity]);
    r.put64(
        "inv_l",
        [if ch.is_pendulum() {
            1.0 / ch.length
        } else {
            0.0
        }],
    );
    r.put64("drag", [ch.air_drag]);
    r.put64("a_e", [ch.damping_a]);
    r.put64("h_stiff", [sp.h_stiff]);
    r.put64("weights", sp.weights.iter().copied());
    r.put64("kicks", kick_weights(sp.weights));
    r.put64("inv_m", ch.mass.iter().map(|m| 1.0 / m));
    r.put64("k", ch.k.iter().copied());
    r.put64("inv_r", ch.r_min.iter().map(|r| 1.0 / r));
    r.put64("gap", ch.gap.iter().copied());
    let contacts = 0..nb - 1;
    r.put64_pairs(
        "imp_t",
        "imp_d",
        contacts.clone().map(|c| ch.impact_coefficients(c)),
    );
    let stiff = |c| ch.stiffness_coefficients(c, sp.omega_ref);
    r.put64_pairs("stiff_l", "stiff_r", contacts.map(stiff));
    r.finish()
}

/// The state a scene starts from, exactly as the CPU integrator starts,
/// into `out`, laid out as `place` (of `layout::STATE` for the scene's
/// shape) says.
pub(super) fn state<R: Real>(place: &Placement, out: &mut [R], ch: &Chain) {
    let mut r = Region::new(place, out);
    r.put64("v", ch.v0.iter().copied());
    r.put64("d", (0..ch.n_bodies() - 1).map(|c| ch.overlap0(c)));
    // compensations; χ and forces (every contact starts open)
    for zero in [
        "cv",
        "cd",
        "chi",
        "f",
        "t",
        "max_overlap",
        "max_ratio",
        "cx0",
        "ct",
    ] {
        r.fill(zero, R::zero());
    }
    // −1: no contact yet, none released
    r.put64("t_first", [-1.0]);
    r.put64("t_release", [-1.0]);
    r.put64("x0", [ch.x0[0]]);
    r.finish()
}

/// The [`Run`] of scene `i` of a batch: its words (`layout::WORDS`) and its
/// final state (`layout::STATE`, from `h.output`).
pub(super) fn run<R: Real>(ch: &Chain, h: &GpuHeader, i: usize, words: &[u32], reals: &[R]) -> Run {
    let (nb, o, nw) = (h.nb as usize, h.output as usize, h.n_weights as usize);
    let f = |j: usize| reals[o + j].to64();
    let at = |name: &str| f(layout::offset(STATE, name, nb, nw));
    let region = |name: &str| {
        layout::range(STATE, name, nb, nw)
            .map(f)
            .collect::<Vec<f64>>()
    };
    let when = |x: f64| (x >= 0.0).then_some(x);
    let word = |name: &str| {
        words[WORDS.len() * i + WORDS.iter().position(|w| *w == name).expect("a word")]
    };
    let overlap = region("d");
    Run {
        end: layout::end_of(word("end")),
        v: region("v"),
        // displacements are tracked on pendulums only (as on the CPU)
        x: if ch.is_pendulum() {
            ch.positions(at("x0"), &overlap)
        } else {
            vec![f64::NAN; nb]
        },
        overlap,
        steps: word("steps") as u64,
        contacts: word("contacts") as u64,
        t: at("t"),
        t_first_contact: when(at("t_first")),
        t_last_release: when(at("t_release")),
        max_overlap: at("max_overlap"),
        max_overlap_ratio: at("max_ratio"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::engine::{plan, Overrides, Solver};
    use crate::scene::Scene;

    /// A 4-ball pendulum with damping and drag: every parameter differs
    /// from its neighbours and none is zero, so a value in the wrong field
    /// shows.
    fn scene() -> (Chain, StepPlan, Limits) {
        let scene = Scene::from_toml_str(
            "pack.toml",
            "balls = 4\nradius = [0.01, 0.011, 0.012, 0.013]\ndensity = 7850.0\nyoung_modulus = 200e9\npoisson_ratio = 0.3\n\
             gap = [1e-5, 2e-5, 3e-5]\nvelocity = [0.3, 0.0, 0.0, 0.0]\n\
             [pendulum]\nlength = 0.5\n[damping]\nrestitution = 0.9\nair_drag = 0.1\n[stop]\nduration = 1.0\n",
        )
        .expect("scene");
        let ch = Chain::from_scene(&scene).expect("chain");
        let solver = Solver::resolve(&scene, &Overrides::default()).expect("solver");
        let (sp, lim) = plan(&ch, &solver);
        (ch, sp.expect("a step"), lim)
    }

    /// Each field, read by name from a region packed with `fields`.
    fn by_name(fields: &[Field], packed: &[f64], nb: usize, nw: usize) -> Vec<(String, Vec<f64>)> {
        fields
            .iter()
            .map(|(name, _)| {
                let r = layout::range(fields, name, nb, nw);
                (name.to_string(), packed[r].to_vec())
            })
            .collect()
    }

    /// Swapping entries of the layout table (scalars, arrays, both) changes
    /// where values lie but not what each named field holds: the packer
    /// follows the table, so the shader's prelude (generated from the same
    /// table) reads the same values. A packer by position fails this.
    #[test]
    fn packer_follows_the_layout_table_by_name() {
        let (ch, sp, lim) = scene();
        let (nb, nw) = (ch.n_bodies(), sp.weights.len());
        for table in [PARAMS, STATE] {
            let pack = |fields: &[Field]| -> Vec<f64> {
                let place = Placement::new(fields, nb, nw);
                let mut out = vec![f64::NAN; place.len()];
                if table == PARAMS {
                    params::<f64>(&place, &mut out, &ch, &sp, &lim)
                } else {
                    state::<f64>(&place, &mut out, &ch)
                }
                out
            };
            let want = by_name(table, &pack(table), nb, nw);
            let mut sorted = want.clone();
            sorted.sort_by(|a, b| a.0.cmp(&b.0));
            for (i, j) in [(0, 1), (0, table.len() - 1), (2, table.len() - 2)] {
                let mut swapped = table.to_vec();
                swapped.swap(i, j);
                let packed = pack(&swapped);
                assert_ne!(packed, pack(table), "swap {i} {j} moves values");
                let mut got = by_name(&swapped, &packed, nb, nw);
                got.sort_by(|a, b| a.0.cmp(&b.0));
                assert_eq!(got, sorted, "swap of {:?} and {:?}", table[i].0, table[j].0);
            }
        }
        // And the values are the scene's: spot checks by name.
        let place = Placement::new(PARAMS, nb, nw);
        let mut packed = vec![f64::NAN; place.len()];
        params::<f64>(&place, &mut packed, &ch, &sp, &lim);
        let p = by_name(PARAMS, &packed, nb, nw);
        let get = |n: &str| p.iter().find(|f| f.0 == n).expect(n).1.clone();
        assert_eq!(get("h"), vec![sp.h]);
        assert_eq!(get("inv_l"), vec![1.0 / ch.length]);
        assert_eq!(get("drag"), vec![ch.air_drag]);
        assert_eq!(get("gap"), ch.gap);
        assert_eq!(
            get("inv_m"),
            ch.mass.iter().map(|m| 1.0 / m).collect::<Vec<_>>()
        );
    }

    /// A batch of scenes of several shapes (3 to 5 balls, methods of 1 to
    /// 9 substeps; two of one shape that differ), long enough to be packed in parallel: each scene's
    /// regions, where its header says they start, hold what packing it
    /// alone gives, and the regions tile the buffers.
    #[test]
    fn a_batch_packs_each_scene_where_its_header_says() {
        let cases: Vec<(Chain, Solver)> = [
            (3, "verlet"),
            (4, "yoshida4"),
            (5, "kahanli6"),
            (5, "kahanli6"),
        ]
        .iter()
        .enumerate()
        .map(|(k, (n, method))| {
            let mut v = vec!["0.0".to_string(); *n];
            v[0] = format!("{}", 0.5 + 0.1 * k as f64);
            let v = format!("[{}]", v.join(", "));
            let text = format!(
                "balls = {n}\nradius = 0.01\ndensity = 7850.0\nyoung_modulus = 200e9\npoisson_ratio = 0.3\n\
                 gap = 1e-5\nvelocity = {v}\n[solver]\nmethod = \"{method}\"\n"
            );
            let scene = Scene::from_toml_str("batch.toml", &text).expect("scene");
            let ch = Chain::from_scene(&scene).expect("chain");
            (ch, Solver::resolve(&scene, &Overrides::default()).expect("solver"))
        })
        .collect();
        let jobs: Vec<(&Chain, &Solver)> = (0..1500)
            .map(|i| {
                let (ch, s) = &cases[(i * 7) % cases.len()];
                (ch, s)
            })
            .collect();
        let b = batch::<f64>(&jobs);
        let (mut p_end, mut s_end) = (0, 0);
        for (h, (ch, solver)) in b.headers.iter().zip(&jobs) {
            let (sp, lim) = plan(ch, solver);
            let sp = sp.expect("a step");
            let (nb, nw) = (ch.n_bodies(), sp.weights.len());
            assert_eq!((h.nb as usize, h.n_weights as usize), (nb, nw));
            let (pp, ps) = (
                Placement::new(PARAMS, nb, nw),
                Placement::new(STATE, nb, nw),
            );
            let (mut want_p, mut want_s) = (vec![0.0; pp.len()], vec![0.0; ps.len()]);
            params(&pp, &mut want_p, ch, &sp, &lim);
            state(&ps, &mut want_s, ch);
            let (i, o) = (h.input as usize, h.output as usize);
            assert_eq!((i, o), (p_end, s_end), "regions follow one another");
            assert_eq!(b.params[i..i + pp.len()], want_p[..]);
            assert_eq!(b.state[o..o + ps.len()], want_s[..]);
            (p_end, s_end) = (i + pp.len(), o + ps.len());
        }
        assert_eq!((b.params.len(), b.state.len()), (p_end, s_end));
        assert_eq!(b.dts.len(), jobs.len());
    }

    #[test]
    #[should_panic(expected = "not packed")]
    fn a_field_left_out_is_caught() {
        let place = Placement::new(PARAMS, 3, 1);
        let mut out = vec![0.0; place.len()];
        let mut r = Region::<f64>::new(&place, &mut out);
        r.put64("h", [1.0]);
        r.finish();
    }
}
