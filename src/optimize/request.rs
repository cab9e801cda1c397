//! An optimisation as a front end asks for it (the command line, Python):
//! the problem, its outputs and settings checked before any work
//! ([`OptimizeRequest::new`]), then run and written ([`OptimizeRequest::run`]).

use std::path::{Path, PathBuf};

use super::{Best, Finished, Problem, Report};
use crate::backend::{self, BackendChoice};
use crate::engine::{Overrides, Solver};
use crate::error::{flag, InputError};
use crate::output::publish::{write_alone, ALONE_COMPANIONS};
use crate::output::{guard, TableKind};
use crate::request::{Error, SolverSettings};

/// How an optimisation runs (plain values, as a user gave them).
#[derive(Clone, Debug)]
pub struct OptimizeSettings {
    pub backend: BackendChoice,
    /// Worker threads for the CPU backend (default: all cores).
    pub threads: Option<i64>,
    pub solver: SolverSettings,
}

impl Default for OptimizeSettings {
    fn default() -> Self {
        OptimizeSettings {
            backend: BackendChoice::Auto,
            threads: None,
            solver: SolverSettings::default(),
        }
    }
}

/// A checked optimisation: nothing has run yet.
#[derive(Debug)]
pub struct OptimizeRequest {
    pub problem: Problem,
    /// The evaluation table and its format.
    pub out: PathBuf,
    pub format: TableKind,
    /// Where the best design goes, if anywhere.
    pub best: Option<PathBuf>,
    backend: BackendChoice,
    threads: Option<usize>,
    overrides: Overrides,
    solver: Solver,
}

/// What a run did.
#[derive(Clone, Debug)]
pub struct OptimizeSummary {
    pub evaluations: u64,
    pub wall_s: f64,
    /// Seconds in the engine's batch runs.
    pub engine_s: f64,
    /// The backend: its name and adapter.
    pub backend: String,
    pub best: Option<Best>,
    /// The best design as scene TOML (what `best` holds).
    pub best_toml: Option<String>,
}

impl OptimizeRequest {
    /// Check `problem` with `settings`, its table going to `out` (CSV or
    /// Parquet by the name) and its best design to `best`.
    pub fn new(
        problem: Problem,
        out: &Path,
        best: Option<&Path>,
        settings: &OptimizeSettings,
    ) -> Result<OptimizeRequest, InputError> {
        let overrides = settings.solver.overrides()?;
        Solver::check_flags_against(&problem.base, &overrides, &problem.origin)?;
        let solver = Solver::resolve(&problem.base, &overrides)?;
        problem.model.check_solver(&solver)?;
        let Some(format) = TableKind::from_extension(out) else {
            return Err(flag(
                "--out",
                &out.display().to_string(),
                "a name ending in .csv, or .parquet/.pq",
            ));
        };
        let out = guard::output("--out", out, &problem.inputs, ALONE_COMPANIONS)?;
        let best = best
            .map(|b| guard::output("--best", b, &problem.inputs, ALONE_COMPANIONS))
            .transpose()?;
        if best.as_ref() == Some(&out) {
            return Err(flag(
                "--best",
                &out.display().to_string(),
                "another file than --out",
            ));
        }
        let threads = settings.threads.map(crate::request::threads).transpose()?;
        Ok(OptimizeRequest {
            problem,
            out,
            format,
            best,
            backend: settings.backend,
            threads,
            overrides,
            solver,
        })
    }

    /// Run it (`report` told after each generation), write the table and
    /// the best design (when there is a feasible one).
    pub fn run(&self, report: &mut (dyn FnMut(&Report) + Send)) -> Result<OptimizeSummary, Error> {
        let p = &self.problem;
        let backend = backend::choose(self.backend, self.solver.precision).map_err(Error::from)?;
        let varied = crate::model::Varied {
            names: p.variables.iter().map(|v| v.param.name.as_str()).collect(),
            balls: None,
        };
        backend
            .prepare(&p.model.needs(&p.base, &varied, &self.solver))
            .map_err(Error::from)?;
        let (b, o): (&dyn crate::backend::Backend, &Overrides) = (&*backend, &self.overrides);
        let mut work = move || super::run(p, b, o, report);
        let fin: Finished = match self.threads {
            Some(n) => rayon::ThreadPoolBuilder::new()
                .num_threads(n)
                .build()
                .map_err(|e| Error::Runtime(e.into()))?
                .install(work),
            None => work(),
        }
        .map_err(Error::from)?;
        write_alone(&self.out, |w| p.write_table(&fin.rows, self.format, w))
            .map_err(Error::from)?;
        let best_toml = fin
            .best
            .as_ref()
            .map(|b| toml::to_string(&b.spec))
            .transpose()
            .map_err(|e| Error::Runtime(e.into()))?;
        if let (Some(text), Some(path)) = (&best_toml, &self.best) {
            write_alone(path, |w| {
                use std::io::Write;
                Ok(w.write_all(text.as_bytes())?)
            })
            .map_err(Error::from)?;
        }
        Ok(OptimizeSummary {
            evaluations: fin.evaluations,
            wall_s: fin.wall_s,
            engine_s: fin.engine_s,
            backend: format!("{} ({})", backend.name(), backend.adapter()),
            best: fin.best,
            best_toml,
        })
    }
}
