//! Validated configuration: `cli.rs` holds the raw flags as clap parsed them;
//! here they become typed, checked settings before any work starts (the
//! low-level → high-level split of ripgrep's `lowargs`/`hiargs`). Every rule
//! about what a run may do is decided here, once:
//! - the output path (`output::guard`: never an input, a directory, a device,
//!   a FIFO; a symlink is written through);
//! - a setting given both as a flag and in a file: an error naming both,
//!   unless they agree (a flag never silently replaces an axis);
//! - resource limits: threads, the tolerance's round-off floor per precision.

use std::path::PathBuf;

use crate::cli::{flag, parse_shard, BackendChoice, SweepArgs};
use crate::engine::{Overrides, Solver};
use crate::error::InputError;
use crate::output::guard;
use crate::scene::Precision;
use crate::sweep::Sweep;

/// Files a sweep writes beside its output `FILE`.
pub const SWEEP_COMPANIONS: &[&str] = &[
    ".partial",
    ".partial.spec",
    ".json",
    ".json.partial",
    ".lock",
];

/// Most worker threads per core the CPU backend accepts: beyond that a run
/// only spends memory and time spawning threads that wait for a core.
pub const MAX_THREADS_PER_CORE: usize = 8;

/// A checked `cradle sweep`.
pub struct SweepConfig {
    pub sweep: Sweep,
    /// The file really written (`--out`, or the final target of a symlink).
    pub out: PathBuf,
    /// `--out` as given, for messages.
    pub out_given: PathBuf,
    pub backend: BackendChoice,
    pub resume: bool,
    /// 1-based shard K of N.
    pub shard: Option<(u64, u64)>,
    pub threads: Option<usize>,
    pub error_estimate: bool,
    pub overrides: Overrides,
    /// The precision the base scene runs in (flags and file resolved).
    pub precision: Precision,
}

/// `--threads N`: 1 ..= MAX_THREADS_PER_CORE × the cores this process may use.
pub fn threads(n: i64) -> Result<usize, InputError> {
    let cores = std::thread::available_parallelism().map_or(1, |c| c.get());
    let max = MAX_THREADS_PER_CORE * cores;
    if n < 1 || n as u64 > max as u64 {
        return Err(flag(
            "--threads",
            &n.to_string(),
            &format!(
                "1 ..= {max} ({MAX_THREADS_PER_CORE} per core; this machine gives {cores} cores)"
            ),
        ));
    }
    Ok(n as usize)
}

impl SweepConfig {
    pub fn from_args(a: &SweepArgs) -> Result<SweepConfig, InputError> {
        let overrides = a.solver.overrides()?;
        let shard = a.shard.as_deref().map(parse_shard).transpose()?;
        let threads = a.threads.map(threads).transpose()?;
        let sweep = Sweep::load(&a.sweep)?;
        sweep.check_overrides(&overrides)?;
        let out = guard::output("--out", &a.out, &sweep.inputs, SWEEP_COMPANIONS)?;
        let precision = Solver::resolve(&sweep.base, &overrides)?.precision;
        Ok(SweepConfig {
            sweep,
            out,
            out_given: a.out.clone(),
            backend: a.backend,
            resume: a.resume,
            shard,
            threads,
            error_estimate: a.error_estimate,
            overrides,
            precision,
        })
    }
}
