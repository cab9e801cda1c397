// The WGSL twin of src/engine/integrate.rs: same state (contact overlaps δ and
// body velocities), same function names, same order of operations, so the GPU
// gives the CPU's answers. One invocation integrates one scene.
//
// `real` is f32 here; the f64 pipeline is built from this text with the alias
// line replaced (src/backend/gpu.rs). δ^{3/2} is written δ·√δ, never pow:
// f64 pow returns garbage on lavapipe without any error.
//
// A scene may need 10^5 steps; one dispatch runs at most `budget` steps of a
// scene (driver watchdogs on real GPUs; llvmpipe silently cuts loops short once
// an invocation has run about 2^16 loop iterations in all, leaving garbage).
// The state lives in out_real/out_u32 between dispatches and the host
// dispatches again until no scene is running.

alias real = f32;
// Kahan-compensated velocity and overlap updates (Real::COMPENSATED): on for f32.
const COMPENSATED = true;

const MAX_BALLS: u32 = 64u;
// Why a run stopped (engine::End).
const END_SETTLED: u32 = 0u;
const END_STEP_CAP: u32 = 1u;
const END_TIME_CAP: u32 = 2u;
const END_NON_FINITE: u32 = 3u;
// Still integrating: resume at the next dispatch.
const END_RUNNING: u32 = 255u;

// |x| at or above this is treated as non-finite (engine::integrate::FINITE_LIMIT).
const FINITE_LIMIT = 1e30;

// Layout-compatible with backend::gpu::GpuHeader.
struct Header {
    // number of bodies
    nb: u32,
    // offset of this scene's parameters in `params`:
    // h, v_floor, max_time, one (= 1.0), h_min, t_scale, weights[n_weights], inv_m[nb], k[nc], inv_r[nc]
    input: u32,
    // offset of its state (the results once it ends) in `out_real`: v[nb], d[nc],
    // cv[nb], cd[nc], t, t_first (−1: none), t_release (−1: none), max_overlap, max_ratio
    output: u32,
    max_steps: u32,
    // number of Verlet substeps per step (their weights follow h_min in `params`)
    n_weights: u32,
    // grading exponent in quarters (graded_step); 0: steps are not graded
    quarters: u32,
    // steps per dispatch, so that one dispatch stays under ~60,000 loop iterations
    budget: u32,
    pad: u32,
}

@group(0) @binding(0) var<storage, read> headers: array<Header>;
@group(0) @binding(1) var<storage, read> params: array<real>;
@group(0) @binding(2) var<storage, read_write> out_real: array<real>;
// end (END_RUNNING while integrating), steps of each scene
@group(0) @binding(3) var<storage, read_write> out_u32: array<u32>;

var<private> v: array<real, MAX_BALLS>;
var<private> d: array<real, MAX_BALLS>;
var<private> cv: array<real, MAX_BALLS>;
var<private> cd: array<real, MAX_BALLS>;
var<private> f: array<real, MAX_BALLS>;
var<private> inv_m: array<real, MAX_BALLS>;
var<private> k: array<real, MAX_BALLS>;
var<private> inv_r: array<real, MAX_BALLS>;
// 1.0, read from the params buffer: a value the shader compiler cannot see,
// so it cannot simplify the compensated sums in `add` away ((x+y)−x → y).
var<private> one: real;

// engine::contact::hertz_force
fn hertz_force(kc: real, dc: real) -> real {
    if (dc > real(0.0)) {
        return kc * dc * sqrt(dc);
    }
    return real(0.0);
}

// engine::integrate::add — x[i] += inc, Kahan-compensated when COMPENSATED.
fn add(x: ptr<private, array<real, MAX_BALLS>>, cx: ptr<private, array<real, MAX_BALLS>>, i: u32, inc: real) {
    if (COMPENSATED) {
        let y = inc - (*cx)[i];
        let t = ((*x)[i] + y) * one;
        (*cx)[i] = (t - (*x)[i]) - y;
        (*x)[i] = t;
    } else {
        (*x)[i] = (*x)[i] + inc;
    }
}

// engine::integrate::kick — body b is pushed left by contact b, right by b−1.
fn kick(nb: u32, hh: real) {
    add(&v, &cv, 0u, -(hh * f[0] * inv_m[0]));
    for (var b = 1u; b < nb - 1u; b++) {
        add(&v, &cv, b, hh * (f[b - 1u] - f[b]) * inv_m[b]);
    }
    add(&v, &cv, nb - 1u, hh * f[nb - 2u] * inv_m[nb - 1u]);
}

// engine::integrate::forces — returns whether any contact is closed.
fn forces(nc: u32) -> bool {
    var closed = false;
    for (var c = 0u; c < nc; c++) {
        f[c] = hertz_force(k[c], d[c]);
        closed = closed || (d[c] > real(0.0));
    }
    return closed;
}

// engine::integrate::graded_step — small steps near contact kinks: h·(T/tc)^(q/4)
// at time distance T from a kink, at most T/2 before it and 2T after it, never
// below h_min, landing on a kink ahead.
fn graded_step(nc: u32, h: real, h_min: real, tc: real, quarters: u32) -> real {
    var s = h;
    for (var c = 0u; c < nc; c++) {
        let r = v[c] - v[c + 1u];
        let dc = d[c];
        let ar = abs(r);
        if (ar <= real(0.0)) {
            continue;
        }
        let tk = abs(dc) / ar;
        if (tk >= tc || tk >= s + s) {
            continue; // no restriction from this contact
        }
        let ahead = (dc < real(0.0) && r > real(0.0)) || (dc > real(0.0) && r < real(0.0));
        let q = sqrt(sqrt(tk / tc));
        var g = real(1.0);
        for (var j = 0u; j < quarters; j++) {
            g = g * q;
        }
        // Halve the distance to a kink ahead, at most double the distance from
        // one behind: no substep reaches across a kink until the step is h_min.
        var cap = tk + tk;
        if (ahead) {
            cap = tk * real(0.5);
        }
        let sc = max(min(h * g, cap), h_min);
        s = min(s, sc);
    }
    return s;
}

// engine::integrate::integrate
fn integrate(i: u32) {
    if (out_u32[2u * i] != END_RUNNING) {
        return;
    }
    let hd = headers[i];
    let nb = hd.nb;
    let nc = nb - 1u;
    let h = params[hd.input];
    let v_floor = params[hd.input + 1u];
    let max_time = params[hd.input + 2u];
    one = params[hd.input + 3u];
    let h_min = params[hd.input + 4u];
    let t_scale = params[hd.input + 5u];
    let w0 = hd.input + 6u; // substep weights
    let m0 = w0 + hd.n_weights; // inv_m
    let q = m0 + nb;
    let o = hd.output;
    let s = o + 2u * (nb + nc);
    for (var b = 0u; b < nb; b++) {
        inv_m[b] = params[m0 + b];
        v[b] = out_real[o + b];
        cv[b] = out_real[o + nb + nc + b];
    }
    f[nb - 1u] = real(0.0);
    for (var c = 0u; c < nc; c++) {
        k[c] = params[q + c];
        inv_r[c] = params[q + nc + c];
        d[c] = out_real[o + nb + c];
        cd[c] = out_real[o + 2u * nb + nc + c];
    }
    // Forces are a function of δ, so the state needs no forces of its own.
    var closed = forces(nc);
    var t = out_real[s];
    var t_first = out_real[s + 1u];
    var t_release = out_real[s + 2u];
    var max_ov = out_real[s + 3u];
    var max_ratio = out_real[s + 4u];
    var steps = out_u32[2u * i + 1u];
    var end = END_RUNNING;
    for (var it = 0u; it < hd.budget; it++) {
        if (!closed) {
            // Free flight: jump to the next onset, if any.
            var found = false;
            var tau = real(0.0);
            var next = 0u;
            for (var c = 0u; c < nc; c++) {
                let r = v[c] - v[c + 1u];
                if (r > v_floor) {
                    let dt = -d[c] / r;
                    if (!found || dt < tau) {
                        tau = dt;
                        next = c;
                        found = true;
                    }
                }
            }
            if (!found) {
                end = END_SETTLED;
                break;
            }
            let capped = t + tau > max_time;
            if (capped) {
                tau = max(max_time - t, real(0.0));
            }
            if (tau > real(0.0)) {
                for (var c = 0u; c < nc; c++) {
                    d[c] = d[c] + (v[c] - v[c + 1u]) * tau;
                }
                t = t + tau;
            }
            if (capped) {
                end = END_TIME_CAP;
                break;
            }
            d[next] = real(0.0);
            cd[next] = real(0.0);
            if (t_first < real(0.0)) {
                t_first = t;
            }
        }
        if (steps >= hd.max_steps) {
            end = END_STEP_CAP;
            break;
        }
        if (t >= max_time) {
            end = END_TIME_CAP;
            break;
        }
        // One step: velocity-Verlet substeps (kick, drift, forces, kick).
        var step = h;
        if (hd.quarters > 0u) {
            step = graded_step(nc, h, h_min, t_scale, hd.quarters);
        }
        for (var wi = 0u; wi < hd.n_weights; wi++) {
            let ws = params[w0 + wi] * step;
            let hh = ws * real(0.5);
            kick(nb, hh);
            for (var c = 0u; c < nc; c++) {
                add(&d, &cd, c, ws * (v[c] - v[c + 1u]));
            }
            closed = forces(nc);
            kick(nb, hh);
        }
        t = t + step;
        steps += 1u;
        if (closed) {
            for (var c = 0u; c < nc; c++) {
                max_ov = max(max_ov, d[c]);
                max_ratio = max(max_ratio, d[c] * inv_r[c]);
            }
        } else {
            // Every contact just opened: locate each release inside the step.
            for (var c = 0u; c < nc; c++) {
                let d1 = d[c];
                let d0 = d1 - step * (v[c] - v[c + 1u]);
                if (d0 > real(0.0) && d1 <= real(0.0)) {
                    t_release = max(t_release, t - step + step * d0 / (d0 - d1));
                }
            }
        }
        var finite = true;
        for (var b = 0u; b < nb; b++) {
            finite = finite && (abs(v[b]) < real(FINITE_LIMIT));
        }
        if (!finite) {
            end = END_NON_FINITE;
            break;
        }
    }
    for (var b = 0u; b < nb; b++) {
        out_real[o + b] = v[b];
        out_real[o + nb + nc + b] = cv[b];
    }
    for (var c = 0u; c < nc; c++) {
        out_real[o + nb + c] = d[c];
        out_real[o + 2u * nb + nc + c] = cd[c];
    }
    out_real[s] = t;
    out_real[s + 1u] = t_first;
    out_real[s + 2u] = t_release;
    out_real[s + 3u] = max_ov;
    out_real[s + 4u] = max_ratio;
    out_u32[2u * i] = end;
    out_u32[2u * i + 1u] = steps;
}

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    if (gid.x >= arrayLength(&headers)) {
        return;
    }
    integrate(gid.x);
}
