//! Injected I/O faults for the fault-injection tests (the idea of tikv's
//! fail-rs, without its dependency): `CRADLE_FAILPOINT=NAME:K` makes the K-th
//! pass (1-based) of the failpoint `NAME` fail with "No space left on
//! device", as a full disk would. Unset (every normal run), a failpoint costs
//! one load of a cached `None`. Names: `append` (a batch of rows reaching the
//! `.partial`), `sidecar` (the sidecar, before the CSV is renamed),
//! `publish` (any finished file, before it is renamed over its name),
//! `generation` (an optimisation's generation reaching its `.partial`).

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::OnceLock;

fn armed() -> Option<&'static (String, u64)> {
    static SPEC: OnceLock<Option<(String, u64)>> = OnceLock::new();
    SPEC.get_or_init(|| {
        let v = std::env::var("CRADLE_FAILPOINT").ok()?;
        let (name, k) = v.split_once(':')?;
        Some((name.to_string(), k.trim().parse().ok()?))
    })
    .as_ref()
}

/// Fail here if this pass is the armed one.
pub fn check(name: &str) -> std::io::Result<()> {
    static PASSES: AtomicU64 = AtomicU64::new(0);
    match armed() {
        Some((n, k)) if n == name => {
            if PASSES.fetch_add(1, Ordering::SeqCst) + 1 == *k {
                return Err(std::io::Error::from_raw_os_error(28)); // ENOSPC
            }
            Ok(())
        }
        _ => Ok(()),
    }
}
