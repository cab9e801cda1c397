//! A physicist's own program on the typed API: a small sweep (the gap
//! between balls 1 and 2 of a 3-ball cradle, 8 values), run on the CPU,
//! its rows read as they are written.
//!
//!     cargo run --release --example sweep_rows [OUT.csv]
//!
//! Prints each scene's gap, how many balls leave and the last ball's speed,
//! then the summary; the table (and its sidecar) is left at OUT.csv
//! (default: sweep_rows.csv in the system's temporary directory).

use std::sync::{Arc, Mutex};

use hertz_cradle::backend::BackendChoice;
use hertz_cradle::{Hooks, SweepRequest, SweepRow, SweepSettings};

const SWEEP: &str = r#"
[scene]
balls = 3
velocity = [1.0, 0.0, 0.0]

[[axis]]
param = "gap[1]"
linspace = [0.0, 2e-5, 8]
"#;

fn main() -> Result<(), hertz_cradle::Error> {
    let out = std::env::args()
        .nth(1)
        .map(std::path::PathBuf::from)
        .unwrap_or_else(|| std::env::temp_dir().join("sweep_rows.csv"));
    let settings = SweepSettings {
        backend: BackendChoice::Cpu,
        ..SweepSettings::default()
    };
    let req = SweepRequest::from_toml("sweep_rows", SWEEP, ".", &out, &settings)?;
    let rows: Arc<Mutex<Vec<SweepRow>>> = Arc::default();
    let sink = rows.clone();
    let summary = req.run(Hooks {
        command: std::env::args().collect(),
        on_row: Some(Arc::new(move |r: &SweepRow| {
            sink.lock().unwrap().push(r.clone())
        })),
        ..Hooks::default()
    })?;
    println!("{:>10} {:>8} {:>10}", "gap[1] m", "ejected", "v_2 m/s");
    for r in rows.lock().unwrap().iter() {
        let gap = r.params[0].as_f64().unwrap_or(f64::NAN);
        // A sweep of cradles: each row's outcome is a cradle's.
        if let Some(o) = r.outcome.cradle() {
            println!("{gap:>10.2e} {:>8} {:>10.6}", o.ejected, o.v[2]);
        }
    }
    println!(
        "{} scenes ({} ok) in {:.3} s on {} -> {}",
        summary.scenes,
        summary.ok,
        summary.wall_s,
        summary.backend,
        out.display()
    );
    Ok(())
}
