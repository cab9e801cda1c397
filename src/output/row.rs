//! One outcome row, the same for `cradle run --format csv` and every sweep row
//! (docs/SPEC.md §4): `id`, one column per axis, `status`, `v_0`..`v_{N−1}`, on a
//! pendulum the final displacements `x_0`..`x_{N−1}` (m, arc length),
//! `ejected`, `energy_error`, `momentum_error` (empty on a pendulum, where
//! gravity changes momentum), `max_overlap_m`, `steps`, then `contacts`
//! (contact onsets), `energy_left` (final / initial energy), `energy_last`
//! (the last ball's kinetic energy / initial energy), `t_contact`,
//! `t_release`, `dt` (s), `error_estimate` (relative to v_in, with
//! `--error-estimate`; empty otherwise).

use crate::engine::{Outcome, Status};

/// Which per-ball columns a table has.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shape {
    /// The largest number of balls.
    pub width: usize,
    /// Pendulum scenes: final displacements `x_i` too.
    pub pendulum: bool,
}

/// Column names for `axes` and a table of `shape`.
pub fn header(axes: &[String], shape: Shape) -> Vec<String> {
    let width = shape.width;
    let mut h = vec!["id".to_string()];
    h.extend(axes.iter().cloned());
    h.push("status".into());
    h.extend((0..width).map(|i| format!("v_{i}")));
    if shape.pendulum {
        h.extend((0..width).map(|i| format!("x_{i}")));
    }
    for c in [
        "ejected",
        "energy_error",
        "momentum_error",
        "max_overlap_m",
        "steps",
        "contacts",
        "energy_left",
        "energy_last",
        "t_contact",
        "t_release",
        "dt",
        "error_estimate",
    ] {
        h.push(c.into());
    }
    h
}

/// A float as the CSV writes it, into `s` (cleared first; no allocation
/// once `s` has grown): shortest round-trip text; NaN → empty.
///
/// The same text as `format!("{x}")` for 0 and 1e-3 ≤ |x| < 1e7 and
/// `format!("{x:e}")` otherwise (tested against both on millions of values),
/// with the shortest round-trip digits from `ryu` laid out here: std's
/// float formatting was the largest single cost of writing a row.
pub fn num_into(x: f64, s: &mut String) {
    use std::fmt::Write;
    s.clear();
    if x.is_nan() {
        return;
    }
    if x == 0.0 || !x.is_finite() || few_exact_digits(x) {
        if x == 0.0 || (1e-3..1e7).contains(&x.abs()) {
            let _ = write!(s, "{x}");
        } else {
            let _ = write!(s, "{x:e}");
        }
        return;
    }
    let mut buf = ryu::Buffer::new();
    let text = buf.format_finite(x).as_bytes();
    // value = 0.DIGITS × 10^point, DIGITS without leading or trailing zeros.
    let mut digits = [0u8; 24];
    let (mut n, mut int_len, mut point, mut in_int) = (0usize, 0i32, 0i32, true);
    let mut i = (text[0] == b'-') as usize;
    while i < text.len() {
        match text[i] {
            b'.' => in_int = false,
            b'e' => {
                let (neg, rest) = match text[i + 1] {
                    b'-' => (true, &text[i + 2..]),
                    _ => (false, &text[i + 1..]),
                };
                let e = rest.iter().fold(0i32, |a, &d| 10 * a + (d - b'0') as i32);
                point += if neg { -e } else { e };
                break;
            }
            d => {
                int_len += in_int as i32;
                if n == 0 && d == b'0' {
                    point -= 1;
                } else {
                    digits[n] = d;
                    n += 1;
                }
            }
        }
        i += 1;
    }
    point += int_len;
    while n > 0 && digits[n - 1] == b'0' {
        n -= 1;
    }
    // The text, laid out in bytes here and pushed once: at most a sign,
    // "0." and 3 zeros (|x| ≥ 1e-3), 17 digits, 7 zeros (|x| < 1e7) or an
    // exponent of 5 characters ("e-324").
    let mut out = [0u8; 40];
    let mut len = 0;
    let mut push = |bytes: &[u8]| {
        out[len..len + bytes.len()].copy_from_slice(bytes);
        len += bytes.len();
    };
    if x < 0.0 {
        push(b"-");
    }
    if (1e-3..1e7).contains(&x.abs()) {
        if point <= 0 {
            push(b"0.");
            push(&b"000"[..(-point) as usize]);
            push(&digits[..n]);
        } else if point as usize >= n {
            push(&digits[..n]);
            push(&b"0000000"[..point as usize - n]);
        } else {
            push(&digits[..point as usize]);
            push(b".");
            push(&digits[point as usize..n]);
        }
    } else {
        push(&digits[..1]);
        if n > 1 {
            push(b".");
            push(&digits[1..n]);
        }
        push(b"e");
        push(itoa::Buffer::new().format(point - 1).as_bytes());
    }
    s.push_str(std::str::from_utf8(&out[..len]).expect("ASCII digits"));
}

/// The id of a CSV row (its first field), if it has one.
pub fn line_id(line: &[u8]) -> Option<u64> {
    let end = line.iter().position(|&b| b == b',').unwrap_or(line.len());
    std::str::from_utf8(&line[..end]).ok()?.trim().parse().ok()
}

/// Append one CSV field as the `csv` crate writes it (RFC 4180, quotes only
/// where needed): quoted, with quotes doubled, when it holds a comma, a
/// quote or a line break. Sweep rows are written with this; the header and
/// `cradle run --format csv` with `csv::Writer` (a test holds them equal).
pub fn push_csv_field(out: &mut Vec<u8>, field: &str) {
    let b = field.as_bytes();
    if b.iter().any(|&c| matches!(c, b',' | b'"' | b'\n' | b'\r')) {
        out.push(b'"');
        for &c in b {
            if c == b'"' {
                out.push(b'"');
            }
            out.push(c);
        }
        out.push(b'"');
    } else {
        out.extend_from_slice(b);
    }
}

/// Whether the exact decimal value of `x` has at most 18 significant digits
/// (or is too large to tell cheaply). Only then can it lie exactly halfway
/// between two shortest candidates, where ryu rounds half to even and std
/// half up; `num_into` leaves those to std (they are "round" numbers: small
/// integers, halves, quarters …, and cheap for std too).
fn few_exact_digits(x: f64) -> bool {
    let bits = x.abs().to_bits();
    let biased = ((bits >> 52) & 0x7ff) as i32;
    let fraction = bits & ((1u64 << 52) - 1);
    let (mut m, mut e) = if biased == 0 {
        (fraction, -1074)
    } else {
        (fraction | (1u64 << 52), biased - 1075)
    };
    let tz = m.trailing_zeros();
    m >>= tz;
    e += tz as i32;
    // x = m · 2^e with m odd.
    const LIMIT: u128 = 1_000_000_000_000_000_000;
    if e < 0 {
        // m · 2^-k = m · 5^k / 10^k: m · 5^k's digits (odd: no trailing
        // zero), more than 18 once k > 26.
        let k = (-e) as u32;
        return k <= 26 && (m as u128) * 5u128.pow(k) < LIMIT;
    }
    let mut v = match (m as u128).checked_shl(e as u32) {
        Some(v) if e < 75 => v,
        _ => return true,
    };
    while v >= LIMIT && v.is_multiple_of(10) {
        v /= 10;
    }
    v < LIMIT
}

/// The fields of one row; missing balls (N below `width`) are empty. A
/// `non_finite` run's state is garbage (±inf, 1e130): its velocities,
/// displacements, `ejected` and energy/momentum/overlap columns are empty
/// rather than numbers that look like results.
pub fn fields(id: u64, axis_values: &[String], o: &Outcome, shape: Shape) -> Vec<String> {
    let mut r = Vec::with_capacity(14 + axis_values.len() + 2 * shape.width);
    let axes = |f: &mut dyn FnMut(Field)| axis_values.iter().for_each(|a| f(Field::Text(a)));
    emit(id, axes, o, shape, &mut String::new(), &mut |x| {
        r.push(x.to_string())
    });
    r
}

/// One field of a row, typed: what a Parquet column stores and what the CSV
/// prints ([`emit`]). `Num(NaN)` and `Null` are both missing (an empty CSV
/// cell, a Parquet null).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Field<'a> {
    Int(u64),
    Num(f64),
    Text(&'a str),
    Null,
}

/// A field that owns its text: a cell of a typed row (the typed API's
/// [`crate::sweep::session::SweepRow`]).
#[derive(Clone, Debug, PartialEq)]
pub enum Cell {
    Int(u64),
    Num(f64),
    Text(String),
    Null,
}

impl Cell {
    /// A field of this crate's CSV text read back as a column of type `t`
    /// types it: an empty field is `Null`; a number that does not parse is
    /// kept as text (it then equals no number).
    pub fn parse(text: &str, t: ColType) -> Cell {
        match t {
            _ if text.is_empty() => Cell::Null,
            ColType::Int => text
                .parse()
                .map_or_else(|_| Cell::Text(text.to_string()), Cell::Int),
            ColType::Num => text
                .parse()
                .map_or_else(|_| Cell::Text(text.to_string()), Cell::Num),
            ColType::Text | ColType::Status => Cell::Text(text.to_string()),
        }
    }
}

impl From<Field<'_>> for Cell {
    fn from(f: Field<'_>) -> Cell {
        match f {
            Field::Int(x) => Cell::Int(x),
            Field::Num(x) => Cell::Num(x),
            Field::Text(t) => Cell::Text(t.to_string()),
            Field::Null => Cell::Null,
        }
    }
}

impl Cell {
    /// The cell as the field a table writes.
    pub fn field(&self) -> Field<'_> {
        match self {
            Cell::Int(x) => Field::Int(*x),
            Cell::Num(x) => Field::Num(*x),
            Cell::Text(t) => Field::Text(t),
            Cell::Null => Field::Null,
        }
    }

    /// The cell as a number, if it is one (an integer too).
    pub fn as_f64(&self) -> Option<f64> {
        match self {
            Cell::Int(x) => Some(*x as f64),
            Cell::Num(x) => Some(*x),
            _ => None,
        }
    }
}

impl<'a> Field<'a> {
    /// A CSV cell of a column of type `t` back as the field it was written
    /// from (the CSV's numbers are shortest round-trip text: exact).
    pub fn parse(cell: &'a str, t: ColType) -> Field<'a> {
        match t {
            _ if cell.is_empty() => Field::Null,
            ColType::Int => cell.parse().map_or(Field::Null, Field::Int),
            ColType::Num => cell.parse().map_or(Field::Null, Field::Num),
            ColType::Text | ColType::Status => Field::Text(cell),
        }
    }
}

/// The type of a column (its Parquet/Arrow type: `Int` → Int64, `Num` →
/// Float64, `Text` → UTF-8, `Status` → a dictionary-encoded string).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ColType {
    Int,
    Num,
    Text,
    Status,
}

/// Column types of a table with axis columns of `axes` types and `shape`,
/// parallel to [`header`].
pub fn column_types(axes: &[ColType], shape: Shape) -> Vec<ColType> {
    use ColType::*;
    let mut t = vec![Int];
    t.extend_from_slice(axes);
    t.push(Status);
    t.extend(std::iter::repeat_n(
        Num,
        shape.width * (1 + shape.pendulum as usize),
    ));
    t.extend([Int, Num, Num, Num, Int, Int, Num, Num, Num, Num, Num, Num]);
    t
}

/// The fields of one row, in order, as text to `out` (what [`fields`]
/// collects; a sweep writes them straight into its CSV buffer). `axes` emits
/// the axis columns; `scratch` is reused for number text.
pub fn emit(
    id: u64,
    axes: impl FnOnce(&mut dyn FnMut(Field)),
    o: &Outcome,
    shape: Shape,
    scratch: &mut String,
    out: &mut dyn FnMut(&str),
) {
    emit_fields(id, axes, o, shape, &mut |f| out(field_text(f, scratch)));
}

/// A field as the CSV writes it (text in `scratch` for numbers).
pub fn field_text<'a>(f: Field<'a>, scratch: &'a mut String) -> &'a str {
    match f {
        Field::Int(x) => {
            scratch.clear();
            scratch.push_str(itoa::Buffer::new().format(x));
            scratch
        }
        Field::Num(x) => {
            num_into(x, scratch);
            scratch
        }
        Field::Text(t) => t,
        Field::Null => "",
    }
}

/// The fields of one row, in order and typed, to `out`.
pub fn emit_fields(
    id: u64,
    axes: impl FnOnce(&mut dyn FnMut(Field)),
    o: &Outcome,
    shape: Shape,
    out: &mut dyn FnMut(Field),
) {
    out(Field::Int(id));
    axes(out);
    emit_outcome(o, shape, out);
}

/// The outcome's fields of a row (after its id and axes), in order.
pub fn emit_outcome(o: &Outcome, shape: Shape, out: &mut dyn FnMut(Field)) {
    let garbage = o.status == Status::NonFinite;
    let state = |x: f64| if garbage { Field::Null } else { Field::Num(x) };
    out(Field::Text(o.status.name()));
    for i in 0..shape.width {
        out(o.v.get(i).map_or(Field::Null, |&v| state(v)));
    }
    if shape.pendulum {
        for i in 0..shape.width {
            out(o.x.get(i).map_or(Field::Null, |&x| state(x)));
        }
    }
    if o.status == Status::Invalid || garbage {
        out(Field::Null)
    } else {
        out(Field::Int(o.ejected as u64))
    }
    for x in [o.energy_error, o.momentum_error, o.max_overlap_m] {
        out(state(x));
    }
    out(Field::Int(o.steps));
    out(Field::Int(o.contacts));
    out(state(o.energy_left));
    out(state(o.energy_last));
    for x in [o.t_contact, o.t_release, o.dt, o.error_estimate] {
        out(Field::Num(x));
    }
}

/// A human-readable table of one outcome (`cradle run`).
pub fn table(name: &str, v_in: f64, v0: &[f64], o: &Outcome, pendulum: bool) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    let _ = writeln!(s, "scene   {name}");
    let _ = writeln!(s, "status  {}", o.status);
    if pendulum {
        let _ = writeln!(
            s,
            "\n ball   v_initial (m/s)   v_final (m/s)   v_final / v_in   x_final (m)"
        );
    } else {
        let _ = writeln!(
            s,
            "\n ball   v_initial (m/s)   v_final (m/s)   v_final / v_in"
        );
    }
    for (i, (a, b)) in v0.iter().zip(&o.v).enumerate() {
        let _ = write!(s, " {i:>4}   {a:>15.6}   {b:>13.8}   {:>14.8}", b / v_in);
        if pendulum {
            let _ = write!(s, "   {:>11.4e}", o.x[i]);
        }
        let _ = writeln!(s);
    }
    let _ = writeln!(s);
    let _ = writeln!(
        s,
        "ejected          {}  (balls leaving the far end faster than half the fastest, in order)",
        o.ejected
    );
    let _ = writeln!(s, "energy_error     {:.3e}  (relative)", o.energy_error);
    if o.momentum_error.is_nan() {
        // A pendulum's balls are pulled by their strings: no conservation.
        let _ = writeln!(
            s,
            "momentum_error   n/a (pendulum: the strings take momentum)"
        );
    } else {
        let _ = writeln!(s, "momentum_error   {:.3e}  (relative)", o.momentum_error);
    }
    let _ = writeln!(
        s,
        "energy_left      {:.9}  (final / initial)",
        o.energy_left
    );
    let _ = writeln!(s, "max_overlap      {:.6e} m", o.max_overlap_m);
    let _ = writeln!(s, "contacts         {}", o.contacts);
    let _ = writeln!(
        s,
        "contact          {:.6e} s .. {:.6e} s",
        o.t_contact, o.t_release
    );
    let _ = writeln!(s, "steps            {}  (dt = {:.4e} s)", o.steps, o.dt);
    s
}

#[cfg(test)]
mod tests {
    /// `num_into` into a fresh string.
    fn num(x: f64) -> String {
        let mut s = String::new();
        super::num_into(x, &mut s);
        s
    }

    #[test]
    fn numbers_round_trip() {
        for x in [
            0.0,
            1.0,
            -0.07109,
            1e-14,
            2.6055e-5,
            123456789.0,
            -1.0 / 3.0,
        ] {
            assert_eq!(num(x).parse::<f64>().unwrap(), x);
        }
        assert_eq!(num(f64::NAN), "");
    }

    #[test]
    fn csv_fields_are_quoted_as_the_csv_crate_does() {
        for row in [
            vec![
                "1",
                "a,b",
                "say \"hi\"",
                "x\ny",
                "",
                "=---",
                "r\rq",
                "plain",
            ],
            vec!["", ""],
        ] {
            let mut want = Vec::new();
            {
                let mut w = csv::Writer::from_writer(&mut want);
                w.write_record(&row).unwrap();
                w.flush().unwrap();
            }
            let mut got = Vec::new();
            for (k, f) in row.iter().enumerate() {
                if k > 0 {
                    got.push(b',');
                }
                super::push_csv_field(&mut got, f);
            }
            got.push(b'\n');
            assert_eq!(
                String::from_utf8(got).unwrap(),
                String::from_utf8(want).unwrap()
            );
        }
    }

    /// `num` is std's Display / LowerExp text, byte for byte.
    #[test]
    fn numbers_match_std_formatting() {
        let std_text = |x: f64| {
            if x == 0.0 || (1e-3..1e7).contains(&x.abs()) {
                format!("{x}")
            } else {
                format!("{x:e}")
            }
        };
        let mut special = vec![
            0.0,
            -0.0,
            1.0,
            -1.0,
            1e-3,
            0.001,
            9.999999999999999e-4,
            1e7,
            9999999.0,
            9999999.999999998,
            1e-7,
            1.5e-7,
            123456789.0,
            1e16,
            1e300,
            5e-324,
            f64::MAX,
            f64::MIN_POSITIVE,
            0.1,
            0.3,
            2.6055e-5,
            -0.07109,
            1e22,
            1e23,
            f64::INFINITY,
            f64::NEG_INFINITY,
        ];
        // Every power of ten and its neighbours.
        for e in -300..308 {
            let p = 10f64.powi(e);
            special.extend([
                p,
                f64::from_bits(p.to_bits() + 1),
                f64::from_bits(p.to_bits() - 1),
            ]);
        }
        let mut x = 0x9E3779B97F4A7C15u64;
        let mut next = || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            x
        };
        let random = (0..2_000_000).map(|i| {
            let r = next();
            if i % 2 == 0 {
                f64::from_bits(r) // any bit pattern
            } else {
                // values of the size the tables hold
                (r >> 11) as f64 / (1u64 << 53) as f64 * 10f64.powi((r % 24) as i32 - 12)
            }
        });
        let mut s = String::new();
        for v in special.into_iter().chain(random) {
            if v.is_nan() {
                continue;
            }
            super::num_into(v, &mut s);
            assert_eq!(s, std_text(v), "{:?}", v.to_bits());
        }
    }

    #[test]
    fn a_non_finite_row_shows_no_garbage_state() {
        use crate::engine::{Outcome, Status};
        let o = Outcome {
            status: Status::NonFinite,
            v: vec![f64::INFINITY, -1e130, 0.5],
            ejected: 2,
            energy_error: f64::INFINITY,
            momentum_error: 1e130,
            max_overlap_m: f64::NEG_INFINITY,
            steps: 77,
            energy_left: 1e130,
            energy_last: f64::INFINITY,
            contacts: 3,
            x: vec![1e130; 3],
            t_end: 1.0,
            t_contact: 1e-4,
            t_release: 2e-4,
            dt: 1e-7,
            error_estimate: f64::NAN,
        };
        let shape = super::Shape {
            width: 3,
            pendulum: true,
        };
        let f = super::fields(4, &["0.5".into()], &o, shape);
        let h = super::header(&["mass".into()], shape);
        let col = |c: &str| f[h.iter().position(|x| x == c).unwrap()].as_str();
        assert_eq!((col("id"), col("status")), ("4", "non_finite"));
        for c in [
            "v_0",
            "v_1",
            "v_2",
            "x_0",
            "ejected",
            "energy_error",
            "momentum_error",
            "max_overlap_m",
            "energy_left",
            "energy_last",
        ] {
            assert_eq!(col(c), "", "{c}");
        }
        assert_eq!((col("steps"), col("dt")), ("77", "1e-7"));
        assert!(f.iter().all(|x| !x.contains("inf") && !x.contains("e130")));
    }
}
