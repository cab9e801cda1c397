//! Command-line interface of `cradle` (SPEC §4). Raw flags are parsed here and
//! checked into typed values before any work starts.

use std::path::PathBuf;

use clap::{Parser, Subcommand, ValueEnum};

use crate::engine::Overrides;
use crate::error::InputError;
use crate::scene::{Method, Precision};

#[derive(Parser, Debug)]
#[command(
    name = "cradle",
    version,
    about = "Newton's cradles with Hertzian contacts: one scene, or sweeps of thousands",
    after_help = "Examples:\n  cradle scenes\n  cradle run cradle-1\n  cradle run my_scene.toml --format csv\n  cradle run seed-glued-pair-into-three --trace trace.csv"
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Simulate one scene (a TOML file or a built-in name) and print its outcome.
    #[command(
        after_help = "Examples:\n  cradle run cradle-2\n  cradle run scene.toml --format csv --precision f32\n  cradle run cradle-1 --trace t.csv --trace-dt 1e-6"
    )]
    Run {
        /// Scene TOML file, or a built-in scene name (see `cradle scenes`).
        scene: String,
        /// Output format.
        #[arg(long, value_enum, default_value_t = Format::Table)]
        format: Format,
        /// Write the trajectory (t, x_0.., v_0..; SI units) as CSV to FILE.
        #[arg(long, value_name = "FILE")]
        trace: Option<PathBuf>,
        /// Trace row spacing in simulated seconds [default: 1/20 of the shortest contact time].
        #[arg(long, value_name = "DT", requires = "trace")]
        trace_dt: Option<f64>,
        #[command(flatten)]
        solver: SolverFlags,
    },
    /// List the built-in scenes.
    Scenes,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Format {
    Table,
    Csv,
}

/// Flags that override a scene's `[solver]` table.
#[derive(clap::Args, Debug, Clone, Default)]
pub struct SolverFlags {
    /// Arithmetic precision: f32 or f64 [default: f64].
    #[arg(long)]
    pub precision: Option<String>,
    /// Target error of outcome velocities relative to v_in [default: 1e-6 (f64), 1e-5 (f32)].
    #[arg(long)]
    pub tolerance: Option<f64>,
    /// Integration method [default: verlet].
    #[arg(long)]
    pub method: Option<String>,
}

impl SolverFlags {
    pub fn overrides(&self) -> Result<Overrides, InputError> {
        let precision = match &self.precision {
            None => None,
            Some(p) => {
                Some(Precision::parse(p).ok_or_else(|| flag("--precision", p, "f32 or f64"))?)
            }
        };
        let method = match &self.method {
            None => None,
            Some(m) => Some(
                Method::parse(m)
                    .ok_or_else(|| flag("--method", m, &format!("one of: {}", Method::names())))?,
            ),
        };
        let tolerance = match self.tolerance {
            None => None,
            Some(t) if t.is_finite() && t > 0.0 && t < 1.0 => Some(t),
            Some(t) => return Err(flag("--tolerance", &t.to_string(), "a number in (0, 1)")),
        };
        Ok(Overrides {
            method,
            precision,
            tolerance,
        })
    }
}

pub fn flag(flag: &str, value: &str, allowed: &str) -> InputError {
    InputError::Flag {
        flag: flag.into(),
        value: value.into(),
        allowed: allowed.into(),
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn clap_definition_is_consistent() {
        use clap::CommandFactory;
        super::Cli::command().debug_assert();
    }
}
