//! An optimisation as a front end asks for it (the command line, Python):
//! the problem, its outputs and settings checked before any work
//! ([`OptimizeRequest::new`]), then run and written ([`OptimizeRequest::run`]).

use std::path::{Path, PathBuf};

use super::{Best, Finished, Problem, Report};
use crate::backend::{self, BackendChoice};
use crate::engine::{Overrides, Solver};
use crate::error::{flag, InputError};
use crate::output::publish::{write_alone, write_with};
use crate::output::row::Cell;
use crate::output::{guard, TableKind};
use crate::request::{Error, SolverSettings};

/// How an optimisation runs (plain values, as a user gave them).
#[derive(Clone, Debug)]
pub struct OptimizeSettings {
    pub backend: BackendChoice,
    /// Worker threads for the CPU backend (default: all cores).
    pub threads: Option<i64>,
    pub solver: SolverSettings,
    /// Continue an interrupted run from `OUT.partial`.
    pub resume: bool,
    /// The command as the user gave it (the sidecar's `command`).
    pub command: Vec<String>,
}

impl Default for OptimizeSettings {
    fn default() -> Self {
        OptimizeSettings {
            backend: BackendChoice::Auto,
            threads: None,
            solver: SolverSettings::default(),
            resume: false,
            command: vec![],
        }
    }
}

/// The suffix of the file an optimisation appends its generations to.
pub const PARTIAL: &str = ".partial";

/// What an output of an optimisation may not be beside: its partial file,
/// the temporary file of the final write, the lock, its sidecar.
const COMPANIONS: &[&str] = &[PARTIAL, crate::output::publish::TMP, ".lock", ".json"];

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
    resume: bool,
    command: Vec<String>,
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
        let out = guard::output("--out", out, &problem.inputs, COMPANIONS)?;
        let best = best
            .map(|b| guard::output("--best", b, &problem.inputs, COMPANIONS))
            .transpose()?;
        if best.as_ref() == Some(&out) || best.as_ref() == Some(&crate::output::sidecar::path(&out))
        {
            return Err(flag(
                "--best",
                &out.display().to_string(),
                "another file than --out and its sidecar (--out's name + .json)",
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
            resume: settings.resume,
            command: settings.command.clone(),
        })
    }

    /// What a resumed run must share with the run it continues: the
    /// problem as resolved, the flags and the version (CRC-32, hex).
    fn fingerprint(&self) -> String {
        fingerprint(&self.problem, &self.overrides)
    }

    /// The rows of the whole generations `partial` holds (a torn last row
    /// and an unfinished generation dropped), checked to be this run's.
    fn earlier(&self, partial: &Path, first: &str) -> Result<Vec<Vec<Cell>>, InputError> {
        let text = std::fs::read_to_string(partial).map_err(|error| InputError::Read {
            path: partial.to_path_buf(),
            error,
        })?;
        let mut lines = text.splitn(2, '\n');
        if lines.next() != Some(first) {
            return Err(flag(
                "--resume",
                &partial.display().to_string(),
                "the partial file of the same problem, flags and version (this one is another run's: remove it, or run without --resume to start over)",
            ));
        }
        let types = self.problem.types();
        // Only whole lines: a kill mid-write leaves a cut-off last line.
        let body = lines.next().unwrap_or("");
        let body = &body[..body.rfind('\n').map_or(0, |i| i + 1)];
        let mut r = csv::ReaderBuilder::new()
            .flexible(true)
            .from_reader(body.as_bytes());
        let header_ok = r.headers().is_ok_and(|h| {
            h.iter()
                .eq(self.problem.header().iter().map(String::as_str))
        });
        if !header_ok {
            return Err(flag(
                "--resume",
                &partial.display().to_string(),
                "a partial file with this problem's columns",
            ));
        }
        let mut rows = vec![];
        for rec in r.records() {
            let Ok(rec) = rec else { break };
            if rec.len() != types.len() {
                break;
            }
            rows.push(
                rec.iter()
                    .zip(&types)
                    .map(|(f, &t)| Cell::parse(f, t))
                    .collect::<Vec<_>>(),
            );
        }
        let lambda = self.problem.population;
        rows.truncate(rows.len() / lambda * lambda);
        Ok(rows)
    }

    /// Run it (`report` told after each generation), write the table and
    /// the best design (when there is a feasible one).
    pub fn run(
        &self,
        cancel: Option<std::sync::Arc<std::sync::atomic::AtomicBool>>,
        report: &mut (dyn FnMut(&Report) + Send),
    ) -> Result<OptimizeSummary, Error> {
        let p = &self.problem;
        let backend = backend::choose(self.backend, self.solver.precision).map_err(Error::from)?;
        backend
            .prepare(&p.model.needs(&p.base, &p.varied(), &self.solver))
            .map_err(Error::from)?;
        let (b, o): (&dyn crate::backend::Backend, &Overrides) = (&*backend, &self.overrides);
        // One writer for the whole run; its generations appended to
        // OUT.partial as they finish (what --resume continues).
        let _lock = crate::output::lock::OutputLock::acquire(&self.out).map_err(Error::from)?;
        let partial = guard::with_suffix(&self.out, PARTIAL);
        let first = format!(
            "# cradle optimize partial, fingerprint {}",
            self.fingerprint()
        );
        let earlier = if self.resume && partial.exists() {
            self.earlier(&partial, &first)?
        } else {
            vec![]
        };
        // The partial file anew: its fingerprint line, then the table so far.
        let mut kept = format!("{first}\n").into_bytes();
        p.write_table(&earlier, TableKind::Csv, &mut kept)
            .map_err(Error::from)?;
        write_with(&partial, |w| Ok(std::io::Write::write_all(w, &kept)?)).map_err(Error::from)?;
        let mut file = std::fs::OpenOptions::new()
            .append(true)
            .open(&partial)
            .map_err(|e| {
                Error::Runtime(anyhow::anyhow!("cannot open {}: {e}", partial.display()))
            })?;
        let mut sink = |rows: &[Vec<Cell>]| -> anyhow::Result<()> {
            use std::io::Write;
            crate::output::failpoint::check("generation")?;
            let mut bytes = vec![];
            super::csv_rows(rows, &mut bytes);
            file.write_all(&bytes)?;
            file.sync_data()?;
            Ok(())
        };
        let cancel = cancel.as_deref();
        // The label inside the pool that ran it: `--threads 1` says 1 thread.
        let work = move || {
            let label = format!("{} ({})", b.name(), b.adapter());
            super::run(p, b, o, earlier, &mut sink, cancel, report).map(|f| (f, label))
        };
        let (fin, label): (Finished, String) = crate::request::pooled(self.threads, work)
            .map_err(Error::Runtime)?
            .map_err(Error::from)?;
        write_with(&self.out, |w| p.write_table(&fin.rows, self.format, w)).map_err(Error::from)?;
        self.write_sidecar(&fin.rows, fin.wall_s, b)
            .map_err(Error::Runtime)?;
        let _ = std::fs::remove_file(&partial);
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
            backend: label,
            best: fin.best,
            best_toml,
        })
    }

    /// Ask/tell: run `designs` (each variable's value, in the problem's
    /// order) as one batch and write their rows to the output (what `run`
    /// writes for a generation: [`super::evaluate`]); the rows back.
    pub fn evaluate(&self, designs: &[Vec<crate::sweep::Value>]) -> Result<Vec<Vec<Cell>>, Error> {
        let p = &self.problem;
        for (k, d) in designs.iter().enumerate() {
            p.check_design(k, d)?;
        }
        let backend = backend::choose(self.backend, self.solver.precision).map_err(Error::from)?;
        backend
            .prepare(&p.model.needs(&p.base, &p.varied(), &self.solver))
            .map_err(Error::from)?;
        let (b, o): (&dyn crate::backend::Backend, &Overrides) = (&*backend, &self.overrides);
        let t0 = std::time::Instant::now();
        let work = || super::evaluate(p, b, o, designs);
        let rows = crate::request::pooled(self.threads, work)
            .map_err(Error::Runtime)?
            .map_err(Error::from)?;
        write_alone(&self.out, |w| p.write_table(&rows, self.format, w)).map_err(Error::from)?;
        let wall_s = t0.elapsed().as_secs_f64();
        self.write_sidecar(&rows, wall_s, b)
            .map_err(Error::Runtime)?;
        Ok(rows)
    }

    /// The table's sidecar (`OUT.json`, as a sweep's: tool, version,
    /// command, the problem file, backend, solver flags, the table's seal),
    /// its `sweep` the resolved optimisation (`optimize`: objective and
    /// direction, variables, method, population, evaluations, seed): what
    /// `cradle explore` reads to draw the convergence and to run a
    /// candidate's scene again. Written after the table, so that a sidecar
    /// never vouches for a table it has not seen.
    fn write_sidecar(
        &self,
        rows: &[Vec<Cell>],
        wall_s: f64,
        backend: &dyn crate::backend::Backend,
    ) -> anyhow::Result<()> {
        use crate::output::sidecar::{self, Sidecar};
        let p = &self.problem;
        let n = rows.len() as u64;
        let ok_col = p.header().iter().position(|h| h == "status");
        let ok = rows
            .iter()
            .filter(|r| ok_col.is_some_and(|k| matches!(&r[k], Cell::Text(t) if t == "ok")))
            .count() as u64;
        let seal = sidecar::seal(&self.out, n)?;
        let sc = Sidecar {
            tool: "cradle".into(),
            version: env!("CARGO_PKG_VERSION").into(),
            git_revision: sidecar::GIT_REVISION.into(),
            command: self.command.clone(),
            sweep_file: p.origin.clone(),
            sweep: serde_json::json!({
                "optimize": {
                    "objective": p.objective.0,
                    "direction": if p.objective.1 { "maximize" } else { "minimize" },
                    "variables": p.variables.iter().map(|v| v.name.clone()).collect::<Vec<_>>(),
                    "method": crate::choice::Choice::name(p.method),
                    "population": p.population,
                    "evaluations": p.generations * p.population as u64,
                    "seed": p.seed,
                },
            }),
            backend: backend.name().into(),
            adapter: backend.adapter(),
            solver: serde_json::json!({ "flags": sidecar::flags(&self.overrides) }),
            ids: [0, n],
            total_scenes: n,
            shard: None,
            scenes_ok: ok,
            scenes_not_ok: n - ok,
            wall_s,
            scenes_per_s: n as f64 / wall_s.max(1e-9),
            resumed_from_row: None,
            wall_s_this_run: None,
            stages_s: None,
            refine: None,
            fingerprint: self.fingerprint(),
            merged_from: None,
            table: Some(seal),
        };
        crate::output::publish::write_atomic(
            &sidecar::path(&self.out),
            sidecar::text(&sc)?.as_bytes(),
        )
    }
}

/// What a resumed run must share with the run it continues, and what an
/// optimisation table's sidecar records: the problem as resolved, the
/// solver flags and the version (CRC-32, hex).
pub fn fingerprint(p: &Problem, overrides: &Overrides) -> String {
    let text = format!(
        "{:?}|{:?}|{:?}|{:?}|{:?}|{}|{}|{}|{:?}|{}",
        p.scene,
        p.variables,
        p.objective,
        p.constraints,
        p.method,
        p.population,
        p.generations,
        p.seed,
        overrides,
        env!("CARGO_PKG_VERSION")
    );
    format!("{:08x}", crc32fast::hash(text.as_bytes()))
}
