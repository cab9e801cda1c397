//! Longer than 600 lines on purpose: every step kernel of the lane state is
//! here, in the order `shaders/cradle/lanes.wgsl` has its twins, so that the two
//! read side by side; `tests/backends.rs` checks the twins cite each other.
//!
//! `L` chains side by side (lane l of every array is one chain) and the step
//! kernels on them: the twins of `lanes.wgsl`'s forces, kicks, drifts,
//! graded steps, exact impacts and free flight, one lane at a time there.

use super::*;

/// Settings shared by every lane of a group.
pub(super) struct Shape {
    pub(super) nb: usize,
    pub(super) nc: usize,
    pub(super) pend: bool,
    pub(super) damped: bool,
    pub(super) dragged: bool,
    pub(super) graded: bool,
    pub(super) quarters: u32,
    pub(super) track_x: bool,
}

/// Declares the lane state once: the struct, `new` (every lane idle) and
/// `move_lane` (one lane's state to another set of lanes) come from one list
/// of fields, per body, per contact and per lane, each with its initial value.
macro_rules! lane_state {
    (
        per_body { $($(#[doc = $bd:literal])* $b:ident: $bt:ty = $bz:expr,)* }
        per_contact { $($(#[doc = $cd:literal])* $c:ident: $ct:ty = $cz:expr,)* }
        per_lane { $($(#[doc = $ld:literal])* $s:ident: $st:ty = $sz:expr,)* }
    ) => {
        /// The state and constants of `L` runs, lane l of each array for run l.
        pub(super) struct Lanes<R, const L: usize> {
            $($(#[doc = $bd])* pub(super) $b: [[$bt; L]; MAX_BALLS],)*
            $($(#[doc = $cd])* pub(super) $c: [[$ct; L]; MAX_BALLS],)*
            $($(#[doc = $ld])* pub(super) $s: [$st; L],)*
        }

        impl<R: Real, const L: usize> Lanes<R, L> {
            pub(super) fn new() -> Box<Self> {
                Box::new(Lanes {
                    $($b: [[$bz; L]; MAX_BALLS],)*
                    $($c: [[$cz; L]; MAX_BALLS],)*
                    $($s: [$sz; L],)*
                })
            }

            /// Move lane l, state and bookkeeping, into lane m of `to`.
            pub(super) fn move_lane<const M: usize>(
                &self,
                sh: &Shape,
                l: usize,
                to: &mut Lanes<R, M>,
                m: usize,
            ) {
                for b in 0..sh.nb {
                    $(to.$b[b][m] = self.$b[b][l];)*
                }
                for c in 0..sh.nc {
                    $(to.$c[c][m] = self.$c[c][l];)*
                }
                $(to.$s[m] = self.$s[l];)*
            }
        }
    };
}

lane_state! {
    per_body {
        v: R = R::zero(),
        /// Kahan compensation of `v` (f32 only).
        cv: R = R::zero(),
        /// Gravity accelerations of the bodies (pendulum; m/s²).
        acc: R = R::zero(),
        inv_m: R = R::zero(),
    }
    per_contact {
        d: R = R::zero(),
        /// Kahan compensation of `d` (f32 only).
        cd: R = R::zero(),
        /// Contact forces (N).
        f: R = R::zero(),
        /// Hunt–Crossley χ of each contact (s/m), set while it is open.
        chi: R = R::zero(),
        /// Overlaps at the start of the step (onset counting).
        d0: R = R::zero(),
        gap: R = R::zero(),
        kc: R = R::zero(),
        /// 1/radius of the smaller ball of each contact.
        inv_r: f64 = 0.0,
        /// Largest overlap of each contact after a step (m); folded into
        /// `max_ov` and `max_ratio` when the run ends.
        dmax: R = R::zero(),
        /// Closed-form impact coefficients of each contact
        /// ([`super::contact::impact_coefficients`]).
        imp_t: R = R::zero(),
        imp_d: R = R::zero(),
        /// Stiffness-cap coefficients of each contact
        /// ([`super::Chain::stiffness_coefficients`]).
        stiff_l: R = R::zero(),
        stiff_r: R = R::zero(),
    }
    per_lane {
        /// Displacement of body 0 (m) and its compensation.
        x0: R = R::zero(),
        cx0: R = R::zero(),
        g: R = R::zero(),
        inv_l: R = R::zero(),
        drag: R = R::zero(),
        a_e: R = R::zero(),
        v_floor: R = R::zero(),
        hr: R = R::zero(),
        h_free: R = R::zero(),
        h_min: R = R::zero(),
        t_scale: R = R::zero(),
        /// The step each lane takes now (0: idle lane).
        step: R = R::zero(),
        closed: bool = false,
        /// Largest overlap seen (m) and its ratio to the smaller radius.
        max_ov: f64 = 0.0,
        max_ratio: f64 = 0.0,
        exact: bool = false,
        /// The stiffness cap's step.
        h_stiff: R = R::zero(),
        run: Book = IDLE,
    }
}

/// A lane's bookkeeping, in f64.
#[derive(Clone, Copy)]
pub(super) struct Book {
    /// Index of the task in the lane; `None`: idle.
    pub(super) task: Option<usize>,
    pub(super) t: f64,
    pub(super) steps: u64,
    pub(super) contacts: u64,
    pub(super) t_first: Option<f64>,
    pub(super) t_release: Option<f64>,
    /// The step lands on a pendulum's duration.
    pub(super) last: bool,
    pub(super) lim: Limits,
}

pub(super) const IDLE: Book = Book {
    task: None,
    t: 0.0,
    steps: 0,
    contacts: 0,
    t_first: None,
    t_release: None,
    last: false,
    lim: Limits {
        max_steps: 0,
        max_time: 0.0,
    },
};

/// Force of one contact: Hertz, or Hunt–Crossley with closing speed `r`.
#[inline(always)]
pub(super) fn contact<R: Real>(damped: bool, k: R, d: R, chi: R, r: R) -> R {
    if damped {
        contact_force(k, d, chi, r)
    } else {
        hertz_force(k, d)
    }
}

impl<R: Real, const L: usize> Lanes<R, L> {
    /// Put run `i` into lane `l`.
    pub(super) fn load(&mut self, sh: &Shape, l: usize, i: usize, task: &Task) {
        let (ch, plan) = (task.chain, &task.plan);
        let zero = R::zero();
        for b in 0..sh.nb {
            self.v[b][l] = R::of(ch.v0[b]);
            self.inv_m[b][l] = R::of(1.0 / ch.mass[b]);
            self.acc[b][l] = zero;
            self.cv[b][l] = zero;
        }
        let d_init = ch.initial_overlap();
        let mut book = IDLE;
        for c in 0..sh.nc {
            self.d[c][l] = R::of(d_init[c]);
            self.gap[c][l] = R::of(ch.gap[c]);
            self.kc[c][l] = R::of(ch.k[c]);
            self.cd[c][l] = zero;
            self.chi[c][l] = zero;
            self.f[c][l] = zero;
            self.inv_r[c][l] = 1.0 / ch.r_min[c];
            let (a, b) = ch.impact_coefficients(c);
            self.imp_t[c][l] = R::of(a);
            self.imp_d[c][l] = R::of(b);
            let (sl, sr) = ch.stiffness_coefficients(c, plan.omega_ref);
            self.stiff_l[c][l] = R::of(sl);
            self.stiff_r[c][l] = R::of(sr);
        }
        self.h_stiff[l] = R::of(plan.h_stiff);
        self.exact[l] = plan.exact;
        self.x0[l] = R::of(ch.x0[0]);
        self.cx0[l] = zero;
        self.g[l] = R::of(ch.gravity);
        self.inv_l[l] = R::of(if ch.is_pendulum() {
            1.0 / ch.length
        } else {
            0.0
        });
        self.drag[l] = R::of(ch.air_drag);
        self.a_e[l] = R::of(ch.damping_a);
        self.hr[l] = R::of(plan.h);
        self.h_free[l] = R::of(plan.h_free);
        self.h_min[l] = R::of(plan.h_min);
        self.t_scale[l] = R::of(plan.t_scale);
        // Closing speeds at round-off level are noise, not an approach: without
        // this floor two balls left at ±1e-15 m/s would "collide" a billion years
        // later and hit the time cap.
        self.v_floor[l] = closing_speed_floor::<R>(ch.v_in(), plan.settle_rel);
        self.step[l] = zero;
        self.max_ov[l] = 0.0;
        self.max_ratio[l] = 0.0;
        for c in 0..sh.nc {
            self.dmax[c][l] = R::zero();
        }
        book.task = Some(i);
        book.lim = task.lim;
        self.run[l] = book;
        self.closed[l] = self.forces_one(sh, l);
    }

    /// The running lanes, moved into a kernel of `M` lanes (at least as many).
    pub(super) fn narrow<const M: usize>(&self, sh: &Shape) -> Box<Lanes<R, M>> {
        let mut to = Lanes::<R, M>::new();
        let mut m = 0;
        for l in 0..L {
            if self.run[l].task.is_some() {
                self.move_lane(sh, l, &mut to, m);
                m += 1;
            }
        }
        to
    }

    /// Lane l takes task `i`, or idles (step 0, state cleared) if there is none.
    pub(super) fn next<O: Observer>(
        &mut self,
        sh: &Shape,
        l: usize,
        i: Option<usize>,
        tasks: &[Task],
        obs: &mut O,
    ) {
        match i {
            Some(i) => {
                self.load(sh, l, i, &tasks[i]);
                observe(sh, self, l, tasks[i].chain, obs);
            }
            None => {
                for b in 0..sh.nb {
                    self.v[b][l] = R::zero();
                    self.d[b][l] = R::zero();
                    self.f[b][l] = R::zero();
                    self.acc[b][l] = R::zero();
                }
                self.step[l] = R::zero();
                self.run[l] = IDLE;
            }
        }
    }

    /// Forces of lane l's contacts (and gravity on a pendulum); whether any
    /// contact is closed.
    #[inline(always)]
    pub(super) fn forces_one(&mut self, sh: &Shape, l: usize) -> bool {
        let mut closed = false;
        for c in 0..sh.nc {
            let r = self.v[c][l] - self.v[c + 1][l];
            self.f[c][l] = contact(sh.damped, self.kc[c][l], self.d[c][l], self.chi[c][l], r);
            closed |= self.d[c][l] > R::zero();
        }
        if sh.pend {
            let mut x = self.x0[l];
            self.acc[0][l] = -(self.g[l] * pendulum_sin(x * self.inv_l[l]));
            for b in 1..sh.nb {
                x = x - self.gap[b - 1][l] - self.d[b - 1][l];
                self.acc[b][l] = -(self.g[l] * pendulum_sin(x * self.inv_l[l]));
            }
        }
        closed
    }

    /// [`Self::forces_one`] on every lane, one loop over the lanes per contact.
    #[inline(always)]
    pub(super) fn forces(&mut self, sh: &Shape) {
        let zero = R::zero();
        let mut closed = [false; L];
        for c in 0..sh.nc {
            let (k, d, chi, f) = (&self.kc[c], &self.d[c], &self.chi[c], &mut self.f[c]);
            let (va, vb) = (&self.v[c], &self.v[c + 1]);
            // Lanes four at a time (one AVX vector of f64): where the contact
            // is open in all four, the force is 0 without a square root.
            let w = if L.is_multiple_of(4) { 4 } else { L };
            for j in (0..L).step_by(w) {
                let mut any = false;
                for l in j..j + w {
                    any |= d[l] > zero;
                }
                if any {
                    for l in j..j + w {
                        f[l] = contact(sh.damped, k[l], d[l], chi[l], va[l] - vb[l]);
                    }
                } else {
                    f[j..j + w].fill(zero);
                }
                for l in j..j + w {
                    closed[l] |= d[l] > zero;
                }
            }
        }
        self.closed = closed;
        if sh.pend {
            let mut x = self.x0;
            for l in 0..L {
                self.acc[0][l] = -(self.g[l] * pendulum_sin(x[l] * self.inv_l[l]));
            }
            for b in 1..sh.nb {
                for l in 0..L {
                    x[l] = x[l] - self.gap[b - 1][l] - self.d[b - 1][l];
                    self.acc[b][l] = -(self.g[l] * pendulum_sin(x[l] * self.inv_l[l]));
                }
            }
        }
    }

    /// Half a kick of `hh` seconds on every lane: air drag (exact decay), then
    /// contact forces and gravity. Body b is pushed left by contact b and right
    /// by contact b−1; gravity is added after the contact push (as in the
    /// shader's `push`).
    #[inline(always)]
    pub(super) fn kick(&mut self, sh: &Shape, hh: &[R; L]) {
        let nb = sh.nb;
        if sh.dragged {
            for l in 0..L {
                let q = decay(self.drag[l] * hh[l]);
                for b in 0..nb {
                    self.v[b][l] = self.v[b][l] * q;
                    self.cv[b][l] = self.cv[b][l] * q;
                }
            }
        }
        for b in 0..nb {
            for l in 0..L {
                let im = self.inv_m[b][l];
                let mut inc = if b == 0 {
                    -(hh[l] * self.f[0][l] * im)
                } else if b == nb - 1 {
                    hh[l] * self.f[nb - 2][l] * im
                } else {
                    hh[l] * (self.f[b - 1][l] - self.f[b][l]) * im
                };
                if sh.pend {
                    inc = inc + hh[l] * self.acc[b][l];
                }
                add(&mut self.v[b][l], &mut self.cv[b][l], inc);
            }
        }
    }

    /// One step of every lane: velocity-Verlet substeps (kick, drift, forces,
    /// kick) of sizes `w·step`, the closing half kick of each substep joined
    /// with the opening one of the next ([`kick_weights`]).
    #[inline(always)]
    pub(super) fn substeps(&mut self, sh: &Shape, weights: &[f64], kicks: &[f64]) {
        let times = |c: f64, step: &[R; L]| {
            let c = R::of(c);
            let mut hk = [R::zero(); L];
            for l in 0..L {
                hk[l] = c * step[l];
            }
            hk
        };
        self.kick(sh, &times(kicks[0], &self.step));
        for (&w, &k) in weights.iter().zip(&kicks[1..]) {
            let ws = times(w, &self.step);
            for c in 0..sh.nc {
                for l in 0..L {
                    let inc = ws[l] * (self.v[c][l] - self.v[c + 1][l]);
                    add(&mut self.d[c][l], &mut self.cd[c][l], inc);
                }
            }
            if sh.track_x {
                for l in 0..L {
                    let inc = ws[l] * self.v[0][l];
                    add(&mut self.x0[l], &mut self.cx0[l], inc);
                }
            }
            self.forces(sh);
            self.kick(sh, &times(k, &self.step));
        }
    }

    /// The impact that contact c (open, just touching, closing) starts, in
    /// closed form, if nothing else can touch while it lasts: bodies a = c
    /// and b = c+1 leave with the elastic two-body velocities after the
    /// two-body contact time t_c, both having moved V_cm·t_c (the overlap is
    /// 0 at both ends), every other body v·t_c. Isolated: the neighbour
    /// contacts stay open even if a and b moved at the extreme speeds they
    /// pass through, and no other contact closes within t_c. Returns whether
    /// it was taken; the same operations as `exact_impact` in the shader.
    pub(super) fn exact_impact(&mut self, sh: &Shape, l: usize, c: usize) -> bool {
        let zero = R::zero();
        let (a, b) = (c, c + 1);
        let (va, vb) = (self.v[a][l], self.v[b][l]);
        let u = va - vb;
        let (ia, ib) = (self.inv_m[a][l], self.inv_m[b][l]);
        let fa = ia / (ia + ib); // m_b / (m_a + m_b)
        let fb = ib / (ia + ib); // m_a / (m_a + m_b)
        let w = fifth_root(u);
        let tc = self.imp_t[c][l] / w;
        let va2 = va - (fa + fa) * u;
        let vb2 = vb + (fb + fb) * u;
        let vcm = va - fa * u;
        if c > 0 && self.d[c - 1][l] + (self.v[a - 1][l] - va.min(va2)).max(zero) * tc > zero {
            return false;
        }
        if b < sh.nc && self.d[b][l] + (vb.max(vb2) - self.v[b + 1][l]).max(zero) * tc > zero {
            return false;
        }
        let speed =
            |v: &[[R; L]; MAX_BALLS], i: usize| if i == a || i == b { vcm } else { v[i][l] };
        for j in 0..sh.nc {
            if (j + 1 < c || j > b) && self.d[j][l] + (self.v[j][l] - self.v[j + 1][l]) * tc > zero
            {
                return false;
            }
        }
        for j in 0..sh.nc {
            if j != c {
                self.d[j][l] = self.d[j][l] + (speed(&self.v, j) - speed(&self.v, j + 1)) * tc;
            }
        }
        if sh.track_x {
            self.x0[l] = self.x0[l] + speed(&self.v, 0) * tc;
        }
        self.v[a][l] = va2;
        self.v[b][l] = vb2;
        self.cv[a][l] = zero;
        self.cv[b][l] = zero;
        let dmax = (self.imp_d[c][l] * u / w).to64();
        self.max_ov[l] = self.max_ov[l].max(dmax);
        self.max_ratio[l] = self.max_ratio[l].max(dmax * self.inv_r[c][l]);
        let book = &mut self.run[l];
        book.t += tc.to64();
        book.contacts += 1;
        book.t_release = Some(book.t_release.map_or(book.t, |x: f64| x.max(book.t)));
        true
    }

    /// Free flight of lane l (every contact open): jump to the next onset,
    /// taking isolated impacts in closed form on the way. `Some(end)` when
    /// the run is over.
    #[inline(never)]
    pub(super) fn fly<O: Observer>(
        &mut self,
        sh: &Shape,
        l: usize,
        ch: &Chain,
        obs: &mut O,
    ) -> Option<End> {
        let zero = R::zero();
        let nc = sh.nc;
        loop {
            // Free flight: every contact open. Jump to the next onset, if any.
            let book = &mut self.run[l];
            let mut tau = R::infinity();
            let mut next = None;
            for c in 0..nc {
                let r = self.v[c][l] - self.v[c + 1][l];
                if r > self.v_floor[l] {
                    let dt = -self.d[c][l] / r;
                    if dt < tau {
                        tau = dt;
                        next = Some(c);
                    }
                }
            }
            let Some(next) = next else {
                return Some(End::Settled);
            };
            let mut tau64 = tau.to64();
            let capped = book.t + tau64 > book.lim.max_time;
            if capped {
                tau64 = (book.lim.max_time - book.t).max(0.0);
                tau = R::of(tau64);
            }
            if tau > zero {
                for c in 0..nc {
                    let r = self.v[c][l] - self.v[c + 1][l];
                    let d = self.d[c][l] + r * tau;
                    // A closing speed at or below the floor is no onset, but
                    // while the rest of the chain goes on the pair must not
                    // pass through each other: it stops touching (its collision
                    // would change velocities by less than the floor).
                    self.d[c][l] = if r > zero && r <= self.v_floor[l] {
                        d.min(zero)
                    } else {
                        d
                    };
                }
                if sh.track_x {
                    self.x0[l] = self.x0[l] + self.v[0][l] * tau;
                }
                book.t += tau64;
                observe(sh, self, l, ch, obs);
            }
            let book = &mut self.run[l];
            if capped {
                return Some(End::TimeCap);
            }
            self.d[next][l] = zero; // the onset, exactly
            self.cd[next][l] = zero;
            book.t_first.get_or_insert(book.t);
            // An isolated impact is over in one jump; then free flight again.
            if !(self.exact[l] && self.exact_impact(sh, l, next)) {
                break;
            }
            observe(sh, self, l, ch, obs);
        }
        None
    }

    /// Lane l before its next step: free flight to the next onset (free line),
    /// then the end checks. `Some(end)` when the run is over.
    #[inline(always)]
    pub(super) fn ready<O: Observer>(
        &mut self,
        sh: &Shape,
        l: usize,
        ch: &Chain,
        obs: &mut O,
    ) -> Option<End> {
        if !self.closed[l] && !sh.pend {
            if let Some(end) = self.fly(sh, l, ch, obs) {
                return Some(end);
            }
        }
        let book = &mut self.run[l];
        if sh.pend && book.t >= book.lim.max_time {
            return Some(End::Duration);
        }
        if book.steps >= book.lim.max_steps {
            return Some(End::StepCap);
        }
        if book.t >= book.lim.max_time {
            return Some(End::TimeCap);
        }
        None
    }

    /// The step of every lane (0 for an idle one): graded near kinks; on a
    /// pendulum long in free flight and landing exactly on the duration. Then
    /// the overlaps at its start and, damped, each contact's χ.
    #[inline(always)]
    pub(super) fn plan_steps(&mut self, sh: &Shape) {
        let zero = R::zero();
        let mut step = self.hr;
        if sh.pend || sh.graded {
            let mut s0 = self.hr;
            if sh.pend {
                for l in 0..L {
                    if !self.closed[l] {
                        s0[l] = self.h_free[l];
                    }
                }
            }
            stiffness_cap(
                sh.nc,
                &self.d,
                &self.stiff_l,
                &self.stiff_r,
                &self.h_stiff,
                &self.h_min,
                &mut s0,
            );
            let acc = Accel {
                f: &self.f,
                inv_m: &self.inv_m,
                g: &self.acc,
                pend: sh.pend,
            };
            step = graded_steps(
                sh.nc,
                &self.d,
                &self.v,
                &acc,
                &s0,
                &self.hr,
                &self.h_min,
                &self.t_scale,
                if sh.graded { sh.quarters } else { 0 },
            );
        }
        for l in 0..L {
            let book = &mut self.run[l];
            book.last = false;
            if book.task.is_none() {
                step[l] = zero;
            } else if sh.pend {
                let rest = R::of(book.lim.max_time - book.t);
                if rest <= step[l] {
                    step[l] = rest;
                    book.last = true;
                }
            }
        }
        self.step = step;
        self.d0[..sh.nc].copy_from_slice(&self.d[..sh.nc]);
        if sh.damped {
            for c in 0..sh.nc {
                for l in 0..L {
                    // Hunt–Crossley: χ = a/v_imp, v_imp the closing speed the
                    // contact closes with — or, if it is driven harder while
                    // closed (a gentle touch, then a hit from behind), the
                    // largest closing speed since.
                    let chi = self.a_e[l] / (self.v[c][l] - self.v[c + 1][l]).max(self.v_floor[l]);
                    self.chi[c][l] = if self.d[c][l] <= zero {
                        chi
                    } else {
                        self.chi[c][l].min(chi)
                    };
                }
            }
        }
    }

    /// Every lane after its step: time, overlaps (vectorised), then, on the
    /// lanes where a contact opened or closed, onsets and releases (located
    /// inside the step by linear interpolation of δ; graded methods land on
    /// them anyway) and, for graded methods on elastic contacts, the kink
    /// impulse correction of the crossing step ([`kink_impulse_error`]).
    /// Returns the lanes whose velocities went non-finite.
    #[inline(always)]
    pub(super) fn account(&mut self, sh: &Shape, weights: &[f64], kicks: &[f64]) -> [bool; L] {
        let zero = R::zero();
        let mut event = [false; L];
        for c in 0..sh.nc {
            for l in 0..L {
                let (d0, d1) = (self.d0[c][l], self.d[c][l]);
                event[l] |= (d1 > zero) != (d0 > zero);
                self.dmax[c][l] = hi(self.dmax[c][l], d1);
            }
        }
        let lim = R::of(FINITE_LIMIT);
        let mut bad = [false; L];
        for b in 0..sh.nb {
            for l in 0..L {
                let v = self.v[b][l];
                bad[l] |= v.is_nan() || v.abs() >= lim;
            }
        }
        for l in 0..L {
            let book = &mut self.run[l];
            let h = self.step[l].to64();
            let t_start = book.t;
            book.t = if book.last {
                book.lim.max_time
            } else {
                book.t + h
            };
            book.steps += 1;
            if !event[l] {
                continue;
            }
            for c in 0..sh.nc {
                let (d0, d1) = (self.d0[c][l], self.d[c][l]);
                if sh.graded && !sh.damped && (d1 > zero) != (d0 > zero) {
                    let dj =
                        kink_impulse_error(self.kc[c][l], d0, d1, weights, kicks) * self.step[l];
                    add(
                        &mut self.v[c][l],
                        &mut self.cv[c][l],
                        -(dj * self.inv_m[c][l]),
                    );
                    add(
                        &mut self.v[c + 1][l],
                        &mut self.cv[c + 1][l],
                        dj * self.inv_m[c + 1][l],
                    );
                }
                if d1 > zero {
                    if d0 <= zero {
                        book.contacts += 1;
                        book.t_first.get_or_insert(t_start);
                    }
                } else if d0 > zero {
                    let (d0, d1) = (d0.to64(), d1.to64());
                    let tr = t_start + h * d0 / (d0 - d1);
                    book.t_release = Some(book.t_release.map_or(tr, |x: f64| x.max(tr)));
                }
            }
        }
        bad
    }

    /// The outcome of lane l's run, which ended with `end`.
    pub(super) fn finish(&self, sh: &Shape, l: usize, end: End, ch: &Chain) -> Run {
        let book = &self.run[l];
        let v: Vec<f64> = (0..sh.nb).map(|b| self.v[b][l].to64()).collect();
        let overlap: Vec<f64> = (0..sh.nc).map(|c| self.d[c][l].to64()).collect();
        let x = if sh.track_x {
            ch.positions(self.x0[l].to64(), &overlap)
        } else {
            vec![f64::NAN; sh.nb]
        };
        let (mut max_ov, mut max_ratio) = (self.max_ov[l], self.max_ratio[l]);
        for c in 0..sh.nc {
            let d = self.dmax[c][l].to64();
            max_ov = max_ov.max(d);
            max_ratio = max_ratio.max(d * self.inv_r[c][l]);
        }
        let settled = matches!(end, End::Settled | End::Duration);
        let end = if settled
            && (v.iter().chain(&overlap).any(|x| !x.is_finite())
                || sh.track_x && x.iter().any(|x| !x.is_finite()))
        {
            End::NonFinite
        } else {
            end
        };
        Run {
            end,
            v,
            overlap,
            steps: book.steps,
            t: book.t,
            t_first_contact: book.t_first,
            t_last_release: book.t_release,
            max_overlap: max_ov,
            max_overlap_ratio: max_ratio,
            x,
            contacts: book.contacts,
        }
    }
}

/// Report lane l's state to the observer (a traced run has one lane).
#[inline(always)]
pub(super) fn observe<R: Real, O: Observer, const L: usize>(
    sh: &Shape,
    s: &Lanes<R, L>,
    l: usize,
    ch: &Chain,
    obs: &mut O,
) {
    if O::ACTIVE {
        let d: Vec<f64> = (0..sh.nc).map(|c| s.d[c][l].to64()).collect();
        let x = ch.positions(s.x0[l].to64(), &d);
        let v: Vec<f64> = (0..sh.nb).map(|b| s.v[b][l].to64()).collect();
        obs.state(s.run[l].t, &x, &v);
    }
}
