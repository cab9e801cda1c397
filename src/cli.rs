//! Command-line interface of `cradle` (docs/SPEC.md §4). Raw flags are parsed here and
//! checked into typed values before any work starts.

use std::path::PathBuf;

use clap::{Parser, Subcommand, ValueEnum};

use crate::backend::BackendChoice;
use crate::choice::Choice;
use crate::engine::Model;
use crate::output::TableKind;
use crate::plot::heatmap::{Cmap, Scale};
use crate::request::{RunSettings, SolverSettings, SweepRequest, SweepSettings};
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
        /// Write the trajectory (t, x_0.., v_0..; SI units) to FILE: FILE.csv,
        /// or FILE.parquet/.pq (the same columns).
        #[arg(long, value_name = "FILE")]
        trace: Option<PathBuf>,
        /// Trace row spacing in simulated seconds [default: 1/20 of the shortest contact time].
        #[arg(
            long,
            value_name = "DT",
            requires = "trace",
            allow_negative_numbers = true
        )]
        trace_dt: Option<f64>,
        #[command(flatten)]
        solver: SolverFlags,
    },
    /// Run every scene of a sweep file and write one table row per scene (CSV or Parquet).
    #[command(
        after_help = "Examples:\n  cradle sweep examples/mass_gap.toml --out results/mass_gap.csv\n  cradle sweep big.toml --out big.csv --resume\n  cradle sweep big.toml --out part2.csv --shard 2/4   # then: cradle merge part*.csv --out big.csv"
    )]
    Sweep(SweepArgs),
    /// Join shard tables (CSV or Parquet) into one of their format; refuses if any id is missing or repeated.
    Merge {
        /// Shard tables, all CSV or all Parquet, in any order.
        #[arg(required = true)]
        inputs: Vec<PathBuf>,
        #[arg(long, value_name = "FILE")]
        out: PathBuf,
    },
    /// Write a refined sweep's table (`[refine]`) as the full grid: every scene
    /// not computed takes the row of its nearest computed one.
    Fill {
        /// A refined sweep's table, CSV or Parquet (its sidecar FILE.json beside it).
        table: PathBuf,
        /// The full grid's table, as CSV: FILE.csv.
        #[arg(long, value_name = "FILE")]
        out: PathBuf,
    },
    /// Explore a sweep's phase map in the browser: hover a cell for its row,
    /// click it to see that cradle (trace, animation, comparison models).
    #[command(
        after_help = "Examples:\n  cradle explore results/mass_gap.csv\n  cradle explore big.parquet --port 9000 --open"
    )]
    Explore {
        /// A sweep's table (CSV or Parquet, its sidecar beside it).
        table: PathBuf,
        #[arg(long, default_value_t = 8080)]
        port: u16,
        /// Address to listen on; anything but 127.0.0.1 exposes the page
        /// (and the CPU it runs scenes on) to the network.
        #[arg(long, default_value = "127.0.0.1")]
        host: String,
        /// Open the page in the default browser.
        #[arg(long)]
        open: bool,
    },
    /// Plot a phase diagram of an outcome table, or a trace's space-time diagram.
    #[command(
        after_help = "Examples:\n  cradle plot results/mass_gap.csv --x gap --y 'mass[2]' --z ejected --out ejected.png\n  cradle plot big.csv --x gap --y velocity[0] --z v_4 --where balls=5 --out v4.svg\n  cradle plot --trace trace.csv --out trace.png\n  cradle plot grid.csv --x gap --y velocity --z v_4 --size 3.4x2.6 --out fig2.pdf"
    )]
    Plot {
        /// Outcome table, CSV or Parquet (from `cradle sweep`).
        #[arg(required_unless_present = "trace", conflicts_with = "trace")]
        table: Option<PathBuf>,
        /// A trace, CSV or Parquet (from `cradle run --trace`) instead: positions and velocities against time.
        #[arg(long, value_name = "TRACE")]
        trace: Option<PathBuf>,
        /// Column on the horizontal axis.
        #[arg(long, required_unless_present = "trace")]
        x: Option<String>,
        /// Column on the vertical axis.
        #[arg(long, required_unless_present = "trace")]
        y: Option<String>,
        /// Column that colours the cells.
        #[arg(long, required_unless_present = "trace")]
        z: Option<String>,
        /// Keep only rows with COL = VALUE (repeatable): a slice of a sweep with more axes.
        #[arg(long = "where", value_name = "COL=VALUE")]
        wheres: Vec<String>,
        /// Title [default: the sweep's description and the z column].
        #[arg(long)]
        title: Option<String>,
        /// Colour of the low end: values below take it (panels of a figure share one scale) [default: the column's smallest].
        #[arg(long, allow_negative_numbers = true, conflicts_with = "trace")]
        vmin: Option<f64>,
        /// Colour of the high end: values above take it [default: the column's largest].
        #[arg(long, allow_negative_numbers = true, conflicts_with = "trace")]
        vmax: Option<f64>,
        /// Colour scale [default: auto: log when the values are positive and span over three decades].
        #[arg(long, value_enum, default_value = "auto", conflicts_with = "trace")]
        scale: Scale,
        /// Colour map (coolwarm for signed columns, e.g. with --vmin -X --vmax X).
        #[arg(long, value_enum, default_value = "viridis", conflicts_with = "trace")]
        cmap: Cmap,
        /// Figure size in inches, as matplotlib's figsize [default: 9.6x7.2 for a table, 10x8 for a trace].
        #[arg(long, value_name = "WxH", value_parser = crate::plot::parse_size)]
        size: Option<(f64, f64)>,
        /// Resolution of a PNG in dots per inch (fonts and lines scale with it; SVG and PDF are vector graphics).
        #[arg(long, default_value_t = 100.0)]
        dpi: f64,
        /// Image to write: FILE.png, FILE.svg or FILE.pdf.
        #[arg(long, value_name = "FILE")]
        out: PathBuf,
    },
    /// Write Slurm batch scripts that run a sweep as a job array and merge it.
    Slurm(SlurmArgs),
    /// Search for the design that minimises or maximises an outcome column
    /// (CMA-ES over any sweepable key; docs/SPEC.md §10).
    Optimize(OptimizeArgs),
    /// List the built-in scenes.
    Scenes,
}

/// `cradle slurm`'s raw flags; [`crate::slurm::plan`] checks them.
#[derive(clap::Args, Debug, Clone)]
#[command(
    after_help = "Writes DIR/array.sbatch (one task per shard), DIR/merge.sbatch (checks that every\nshard finished, then merges) and DIR/submit.sh (submits both, the merge after the array).\n\nExamples:\n  cradle slurm examples/mass_gap.toml --shards 8 --time 00:30:00 && slurm-mass_gap/submit.sh\n  cradle slurm big.toml --shards 64 --gpus-per-task 1 --partition gpu --out big.csv\n  sbatch --array=5 slurm-big/array.sbatch     # resubmit shard 5 alone; it resumes"
)]
pub struct SlurmArgs {
    /// Sweep TOML file.
    pub sweep: PathBuf,
    /// Number of shards (array tasks).
    #[arg(long)]
    pub shards: u64,
    /// Merged output table: FILE.csv, or FILE.parquet/.pq (the shards are
    /// written in its format) [default: SWEEP's name .csv in the current directory].
    #[arg(long, value_name = "FILE")]
    pub out: Option<PathBuf>,
    /// Directory for the scripts, shard outputs and logs [default: slurm-SWEEP's name].
    #[arg(long, value_name = "DIR")]
    pub dir: Option<PathBuf>,
    /// Slurm partition.
    #[arg(long)]
    pub partition: Option<String>,
    /// GPUs per task (requested with --gres=gpu:G; the shards then run with --backend gpu).
    #[arg(long, default_value_t = 0)]
    pub gpus_per_task: u32,
    /// CPUs per task (the CPU backend's threads).
    #[arg(long)]
    pub cpus_per_task: Option<u32>,
    /// Time limit per task, Slurm syntax (e.g. 01:00:00).
    #[arg(long)]
    pub time: Option<String>,
    /// The cradle binary the tasks run [default: this one].
    #[arg(long, value_name = "PATH")]
    pub cradle: Option<PathBuf>,
    #[command(flatten)]
    pub solver: SolverFlags,
}

/// `cradle sweep`'s raw flags; [`SweepArgs::request`] checks them.
#[derive(clap::Args, Debug, Clone)]
#[command(
    after_help = "Examples:\n  cradle sweep examples/mass_gap.toml --out results/mass_gap.csv\n  cradle sweep big.toml --out big.csv --resume\n  cradle sweep big.toml --out part2.csv --shard 2/4   # then: cradle merge part*.csv --out big.csv"
)]
pub struct SweepArgs {
    /// Sweep TOML file.
    pub sweep: PathBuf,
    /// Output table, CSV or Parquet (written as FILE.partial, complete under its name at the end; FILE.json
    /// beside it; FILE.lock while running). A new name or a regular file;
    /// a symlink is written through.
    #[arg(long, value_name = "FILE")]
    pub out: PathBuf,
    /// auto: a hardware GPU if there is one, else the CPU.
    #[arg(long, value_enum, default_value_t = BackendChoice::Auto)]
    pub backend: BackendChoice,
    /// Continue an interrupted run into the same --out file.
    #[arg(long)]
    pub resume: bool,
    /// Run only shard K of N (1-based; contiguous id ranges balanced in
    /// expected cost), e.g. 2/4; `slurm`: this task of a Slurm job array.
    #[arg(long, value_name = "K/N|slurm")]
    pub shard: Option<String>,
    /// Worker threads for the CPU backend [default: all cores].
    #[arg(long, allow_negative_numbers = true)]
    pub threads: Option<i64>,
    /// The output's format [default: the one FILE's name says: .csv, or
    /// .parquet/.pq; another name needs --format].
    #[arg(long, value_enum, value_name = "FORMAT")]
    pub format: Option<TableKind>,
    /// Fill the `error_estimate` column: every scene runs a second time with
    /// steps twice as long (Richardson); costs about 60% more.
    #[arg(long)]
    pub error_estimate: bool,
    #[command(flatten)]
    pub solver: SolverFlags,
}

/// `cradle optimize`'s flags.
#[derive(clap::Args, Debug, Clone)]
#[command(
    after_help = "Examples:\n  cradle optimize examples/protector.toml --out runs.csv --best best.toml\n  cradle run best.toml   # the best design, bit for bit"
)]
pub struct OptimizeArgs {
    /// Problem TOML file: a base scene, variables, an objective, constraints, the optimizer (docs/SPEC.md §10).
    pub problem: PathBuf,
    /// Every evaluation as a row: FILE.csv, or FILE.parquet/.pq (written whole at the end).
    #[arg(long, value_name = "FILE")]
    pub out: PathBuf,
    /// The best feasible design as a scene file that `cradle run` reproduces.
    #[arg(long, value_name = "FILE")]
    pub best: Option<PathBuf>,
    /// auto: a hardware GPU if there is one, else the CPU.
    #[arg(long, value_enum, default_value_t = BackendChoice::Auto)]
    pub backend: BackendChoice,
    /// Worker threads for the CPU backend [default: all cores].
    #[arg(long, allow_negative_numbers = true)]
    pub threads: Option<i64>,
    /// Continue an interrupted run from FILE.partial (the generations it
    /// finished are replayed, not run again: the same result as one run).
    #[arg(long)]
    pub resume: bool,
    #[command(flatten)]
    pub solver: SolverFlags,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Format {
    Table,
    Csv,
}

/// The core's closed sets ([`Choice`]) as clap values: their names are the
/// ones the files use (`Method::name`, …), and a bad value gets clap's
/// message with the possible values (exit 2).
macro_rules! value_enum {
    ($($t:ty),*) => {$(
        impl ValueEnum for $t {
            fn value_variants<'a>() -> &'a [Self] {
                <$t as Choice>::ALL
            }
            fn to_possible_value(&self) -> Option<clap::builder::PossibleValue> {
                Some(clap::builder::PossibleValue::new(Choice::name(*self)))
            }
        }
    )*};
}
value_enum!(
    Method,
    Precision,
    Model,
    BackendChoice,
    TableKind,
    Scale,
    Cmap
);

/// Solver settings from the command line (a file's `[solver]` may give them
/// too; the two must agree: `config`).
#[derive(clap::Args, Debug, Clone, Default)]
pub struct SolverFlags {
    /// Arithmetic precision [default: f64]; df64: pairs of f32 (f64's results on GPUs with slow f64).
    #[arg(long, value_enum)]
    pub precision: Option<Precision>,
    /// Target error of outcome velocities relative to v_in [default: 1e-6 (f64, df64), 1e-5 (f32)].
    #[arg(long, allow_negative_numbers = true)]
    pub tolerance: Option<f64>,
    /// Physics model: hertz (integrated contacts), hard-sphere (instantaneous
    /// binary collisions, event-driven) or closure (the seed's simultaneous
    /// separation, touching chains) [default: hertz].
    #[arg(long, value_enum)]
    pub model: Option<Model>,
    /// Integration method: verlet (order 2), suzuki4, yoshida4 (order 4), yoshida6, kahanli6 (order 6) [default: kahanli6].
    #[arg(long, value_enum)]
    pub method: Option<Method>,
}

impl SolverFlags {
    /// The flags as command-line arguments again (for generated scripts).
    pub fn args(&self) -> Vec<String> {
        let mut a = vec![];
        for (k, v) in [
            ("--precision", self.precision.map(|p| p.name().to_string())),
            ("--tolerance", self.tolerance.map(|t| t.to_string())),
            ("--method", self.method.map(|m| m.name().to_string())),
            ("--model", self.model.map(|m| m.name().to_string())),
        ] {
            if let Some(v) = v {
                a.extend([k.to_string(), v]);
            }
        }
        a
    }

    /// The flags as the core's unchecked settings.
    pub fn settings(&self) -> SolverSettings {
        SolverSettings {
            precision: self.precision,
            tolerance: self.tolerance,
            model: self.model,
            method: self.method,
        }
    }
}

impl SweepArgs {
    /// The flags as the core's unchecked settings.
    pub fn settings(&self) -> SweepSettings {
        SweepSettings {
            backend: self.backend,
            resume: self.resume,
            shard: self.shard.clone(),
            threads: self.threads,
            format: self.format,
            error_estimate: self.error_estimate,
            solver: self.solver.settings(),
        }
    }

    /// The checked sweep: every check (flags, the sweep file, the output
    /// path, flags against the file) before any work or any GPU start-up.
    pub fn request(&self) -> Result<SweepRequest, crate::InputError> {
        SweepRequest::from_file(&self.sweep, &self.out, &self.settings())
    }
}

/// `cradle run`'s settings from its flags.
pub fn run_settings(
    trace: Option<PathBuf>,
    trace_dt: Option<f64>,
    solver: &SolverFlags,
) -> RunSettings {
    RunSettings {
        solver: solver.settings(),
        trace,
        trace_dt,
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
