//! `cradle`: the command-line front end. `run()` does the work; `main` prints
//! the whole error chain and exits 2 for bad input, 1 for anything else.

use std::io::Write;
use std::process::ExitCode;

use clap::Parser;

use hertz_cradle::cli::{run_settings, Cli, Command, Format};
use hertz_cradle::output::guard;
use hertz_cradle::output::lock::OutputLock;
use hertz_cradle::output::row;
use hertz_cradle::plot;
use hertz_cradle::scene::builtin;
use hertz_cradle::sweep::merge::merge;
use hertz_cradle::{Hooks, InputError, RunRequest};

fn main() -> ExitCode {
    hertz_cradle::backend::gpu::quiet_mesa_without_session();
    let cli = Cli::parse();
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            if is_broken_pipe(&e) {
                return ExitCode::SUCCESS;
            }
            if e.is::<hertz_cradle::error::Interrupted>() {
                // Said what was kept already; 128 + SIGINT, the shell's code.
                return ExitCode::from(130);
            }
            eprintln!("error: {e:#}");
            if e.chain().any(|c| c.downcast_ref::<InputError>().is_some()) {
                ExitCode::from(2)
            } else {
                ExitCode::from(1)
            }
        }
    }
}

/// A flag set by the first Ctrl-C (or SIGTERM, SIGHUP): the sweep stops
/// once the scenes running finish (no scene or chain starts after it),
/// keeping the rows of every batch finished. A second one
/// ends the process at once (exit 130; `--resume` still continues).
fn stop_on_signal() -> std::sync::Arc<std::sync::atomic::AtomicBool> {
    use std::sync::atomic::{AtomicBool, Ordering};
    let stop = std::sync::Arc::new(AtomicBool::new(false));
    let flag = stop.clone();
    let handler = ctrlc::set_handler(move || {
        if flag.swap(true, Ordering::SeqCst) {
            std::process::exit(130);
        }
        eprintln!(
            "\ncradle: stopping once the scenes running finish (press Ctrl-C again to stop at once)"
        );
    });
    if let Err(e) = handler {
        eprintln!("cradle: warning: Ctrl-C will end the sweep without a word ({e})");
    }
    stop
}

/// Ctrl-C (or SIGTERM, SIGHUP) during `run --trace FILE`: the trace being
/// written (`FILE.tmp`) and its lock are removed, FILE is left as it was,
/// and the run exits 130 saying so (it left `FILE.tmp` behind).
fn forget_trace_on_signal(path: &std::path::Path) {
    use hertz_cradle::output::guard::with_suffix;
    let (tmp, lock) = (
        with_suffix(path, hertz_cradle::output::publish::TMP),
        OutputLock::path_for(path),
    );
    let shown = path.display().to_string();
    let _ = ctrlc::set_handler(move || {
        let _ = std::fs::remove_file(&tmp);
        let _ = std::fs::remove_file(&lock);
        eprintln!("\ncradle: interrupted: no trace written ({shown} is as it was)");
        std::process::exit(130);
    });
}

fn is_broken_pipe(e: &anyhow::Error) -> bool {
    e.chain().any(|c| {
        c.downcast_ref::<std::io::Error>()
            .is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe)
    })
}

fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Sweep(args) => sweep(args),
        Command::Merge { inputs, out } => {
            let target = guard::output(
                "--out",
                &out,
                &inputs,
                hertz_cradle::output::partial::COMPANIONS,
            )?;
            let _lock = OutputLock::acquire(&target)?;
            let n = merge(&inputs, &target)?;
            eprintln!(
                "cradle: merged {} files, {n} rows -> {}",
                inputs.len(),
                out.display()
            );
            Ok(())
        }
        Command::Explore {
            table,
            port,
            host,
            open,
        } => {
            if host != "127.0.0.1" && host != "localhost" && host != "::1" {
                eprintln!("cradle: warning: listening on {host}: anyone who can reach this machine can see the table and run scenes on it");
            }
            hertz_cradle::explore::serve(&table, &host, port, &|url| {
                eprintln!(
                    "cradle: exploring {} at {url} (Ctrl-C to stop)",
                    table.display()
                );
                if open {
                    let _ = std::process::Command::new("xdg-open").arg(url).spawn();
                }
            })
        }
        Command::Fill { table, out } => fill(table, out),
        Command::Plot {
            table,
            trace,
            x,
            y,
            z,
            wheres,
            title,
            vmin,
            vmax,
            scale,
            cmap,
            size,
            dpi,
            out,
        } => {
            let figure = plot::Figure { size, dpi };
            let input = table.iter().chain(&trace).cloned().collect::<Vec<_>>();
            let tmp = plot::tmp_suffix(&out);
            let out_path = guard::output("--out", &out, &input, &[tmp.as_str(), ".lock"])?;
            let out = &out_path;
            // One plot into a file at a time (they would share FILE.tmp.<ext>).
            let _lock = OutputLock::acquire(out)?;
            match (table, trace) {
                (_, Some(tr)) => plot::trace::plot(&tr, title.as_deref(), &figure, out)?,
                (Some(t), None) => plot::heatmap::plot(
                    &t,
                    &plot::heatmap::Args {
                        x: x.unwrap_or_default(),
                        y: y.unwrap_or_default(),
                        z: z.unwrap_or_default(),
                        wheres,
                        title,
                        vmin,
                        vmax,
                        scale,
                        cmap,
                        figure,
                    },
                    out,
                )?,
                (None, None) => unreachable!("clap requires a table or --trace"),
            }
            eprintln!("cradle: wrote {}", out.display());
            Ok(())
        }
        Command::Optimize(args) => optimize(args),
        Command::Slurm(args) => {
            let plan = hertz_cradle::slurm::plan(&args)?;
            for p in hertz_cradle::slurm::write(&plan)? {
                eprintln!("cradle: wrote {}", p.display());
            }
            eprintln!(
                "cradle: submit with {}",
                plan.dir.join("submit.sh").display()
            );
            Ok(())
        }
        Command::Scenes => {
            let mut out = std::io::stdout().lock();
            for b in builtin::BUILTINS {
                writeln!(out, "{:<28} {}", b.name, b.summary)?;
            }
            Ok(())
        }
        Command::Run {
            scene,
            format,
            trace,
            trace_dt,
            solver,
        } => run_scene(scene, format, trace, trace_dt, solver),
    }
}

/// `cradle sweep`: the run with a progress bar, interrupts kept for
/// `--resume`, and its summary on stderr.
fn sweep(args: hertz_cradle::cli::SweepArgs) -> anyhow::Result<()> {
    // Every check (flags, the sweep file, the output path, flags
    // against the file) before any work or any GPU start-up.
    let req = args.request()?;
    let bar = hertz_cradle::progress::Bar::stderr(true);
    let model = req.sweep.model.clone();
    bar.watch(move || model.work_done());
    let cancel = stop_on_signal();
    let total = std::sync::Arc::new(std::sync::atomic::AtomicU64::new(0));
    let on_progress = {
        let (shown, total) = (bar.callback(), total.clone());
        std::sync::Arc::new(move |p: hertz_cradle::sweep::session::Progress| {
            total.store(p.total, std::sync::atomic::Ordering::SeqCst);
            shown(p)
        })
    };
    let run = req.run(Hooks {
        command: std::env::args().collect(),
        on_progress: Some(on_progress),
        cancel: Some(cancel),
        ..Hooks::default()
    });
    drop(bar);
    let out = req.out_given.display();
    let s = match run {
        Err(hertz_cradle::request::Error::Interrupted) => {
            let kept = hertz_cradle::output::partial::resumable_rows(&req.out);
            let total = total.load(std::sync::atomic::Ordering::SeqCst);
            eprintln!(
                "cradle: interrupted: {} of {total} scenes are kept in {out}.partial; run the same command with --resume to continue (without --resume a rerun starts over)",
                kept.unwrap_or(0)
            );
            return Err(hertz_cradle::error::Interrupted.into());
        }
        r => r.map_err(|e| e.into_anyhow())?,
    };
    if let Some((rows, dropped)) = s.resumed {
        let tail = match dropped {
            0 => String::new(),
            b => format!(
                "; dropped the {b} bytes after them (an incomplete or torn last row, or a crash's zero-filled block)"
            ),
        };
        eprintln!("cradle: resumed {out} after {rows} whole rows{tail}");
    }
    if s.already_complete {
        eprintln!("cradle: {out} is already complete; nothing to resume");
    } else {
        eprintln!(
            "cradle: {} scenes ({} ok, {} not ok) in {:.2} s, {}, backend {} -> {out}",
            s.scenes,
            s.ok,
            s.scenes - s.ok,
            s.wall_s,
            hertz_cradle::progress::rate(s.scenes as f64 / s.wall_s.max(1e-9)),
            s.backend,
        );
    }
    Ok(())
}

/// `cradle optimize`: the problem checked, the flags and outputs before
/// any work; a line per generation on stderr; the table and the best
/// design written whole at the end.
fn optimize(args: hertz_cradle::cli::OptimizeArgs) -> anyhow::Result<()> {
    use hertz_cradle::optimize::request::{OptimizeRequest, OptimizeSettings};
    let problem = hertz_cradle::optimize::Problem::load(&args.problem)?;
    let settings = OptimizeSettings {
        backend: args.backend,
        threads: args.threads,
        solver: args.solver.settings(),
        resume: args.resume,
        command: std::env::args().collect(),
    };
    let req = OptimizeRequest::new(problem, &args.out, args.best.as_deref(), &settings)?;
    let column = req.problem.objective.0.clone();
    let generations = std::sync::atomic::AtomicU64::new(0);
    let run = req.run(Some(stop_on_signal()), &mut |r| {
        generations.store(r.generation + 1, std::sync::atomic::Ordering::SeqCst);
        let best = r
            .best
            .map_or("none feasible yet".to_string(), |b| format!("{b:e}"));
        eprintln!(
            "cradle: generation {}/{}: {} evaluations, best {column} {best}",
            r.generation + 1,
            r.generations,
            r.evaluations,
        );
    });
    let s = match run {
        Err(hertz_cradle::request::Error::Interrupted) => {
            eprintln!(
                "cradle: interrupted: {} of {} generations are kept in {}.partial; run the same command with --resume to continue (without --resume a rerun starts over)",
                generations.load(std::sync::atomic::Ordering::SeqCst),
                req.problem.generations,
                req.out.display()
            );
            return Err(hertz_cradle::error::Interrupted.into());
        }
        r => r.map_err(|e| e.into_anyhow())?,
    };
    match (&s.best, &req.best) {
        (Some(b), Some(path)) => eprintln!(
            "cradle: best design (generation {}, candidate {}) -> {}",
            b.generation,
            b.candidate,
            path.display()
        ),
        (None, Some(path)) => {
            eprintln!("cradle: no feasible design: {} not written", path.display())
        }
        _ => {}
    }
    eprintln!(
        "cradle: {} evaluations in {:.2} s ({:.1}% in the engine), backend {}: best {column} = {} -> {}",
        s.evaluations,
        s.wall_s,
        100.0 * s.engine_s / s.wall_s.max(1e-9),
        s.backend,
        s.best
            .as_ref()
            .map_or("none feasible".into(), |b| format!("{:e}", b.objective)),
        req.out.display()
    );
    Ok(())
}

/// `cradle fill`: a refined sweep's table as the full grid.
fn fill(table: std::path::PathBuf, out: std::path::PathBuf) -> anyhow::Result<()> {
    let target = guard::output(
        "--out",
        &out,
        std::slice::from_ref(&table),
        hertz_cradle::output::publish::ALONE_COMPANIONS,
    )?;
    // fill writes CSV text: a name that says another format would hold
    // bytes it does not name (`--out full.parquet` was CSV inside).
    if hertz_cradle::output::TableKind::from_extension(&out)
        != Some(hertz_cradle::output::TableKind::Csv)
    {
        return Err(hertz_cradle::error::flag(
            "--out",
            &out.display().to_string(),
            "a name ending in .csv (fill writes CSV, from a CSV or Parquet table)",
        )
        .into());
    }
    if !table.exists() {
        return Err(hertz_cradle::InputError::Read {
            path: table,
            error: std::io::Error::new(std::io::ErrorKind::NotFound, "no such file"),
        }
        .into());
    }
    let Some(g) = hertz_cradle::sweep::fill::grid(&table)? else {
        return Err(hertz_cradle::InputError::Data {
            path: table,
            what: "not a refined sweep's table (its sidecar has no `refine`)".into(),
        }
        .into());
    };
    let n = hertz_cradle::output::publish::write_alone(&target, |w| {
        hertz_cradle::sweep::fill::fill(&table, &g, &mut |row| {
            w.write_all(row)
                .map_err(|e| anyhow::anyhow!("cannot write {}: {e}", target.display()))
        })
    })?;
    eprintln!("cradle: {n} rows -> {}", target.display());
    Ok(())
}

/// `cradle run`: one scene's outcome as a table or a CSV row.
fn run_scene(
    scene: String,
    format: Format,
    trace: Option<std::path::PathBuf>,
    trace_dt: Option<f64>,
    solver: hertz_cradle::cli::SolverFlags,
) -> anyhow::Result<()> {
    let cfg = RunRequest::from_name(&scene, &run_settings(trace, trace_dt, &solver))
        .map_err(|e| e.into_anyhow())?;
    if let Some((path, _)) = &cfg.trace {
        forget_trace_on_signal(path);
    }
    if let Some(beads) = &cfg.beads {
        let o = cfg.run_chain().map_err(|e| e.into_anyhow())?;
        return print_chain(&cfg.name, beads, &o, format);
    }
    let outcome = cfg.run().map_err(|e| e.into_anyhow())?;
    let chain = &cfg.chain;
    let mut out = std::io::stdout().lock();
    match format {
        Format::Table => write!(
            out,
            "{}",
            row::table(
                &cfg.name,
                chain.v_in(),
                &cfg.scene.velocity,
                &outcome,
                chain.is_pendulum()
            )
        )?,
        Format::Csv => {
            let mut w = csv::Writer::from_writer(&mut out);
            let shape = row::Shape {
                width: cfg.scene.n,
                pendulum: chain.is_pendulum(),
            };
            w.write_record(row::header(&[], shape))?;
            w.write_record(row::fields(0, &[], &outcome, shape))?;
            w.flush()?;
        }
    }
    Ok(())
}

/// `cradle run` of a granular chain: its table, or its row as CSV.
fn print_chain(
    name: &str,
    beads: &hertz_cradle::engine::granular::Beads,
    o: &hertz_cradle::engine::granular::ChainOutcome,
    format: Format,
) -> anyhow::Result<()> {
    use hertz_cradle::output::chain_row;
    let mut out = std::io::stdout().lock();
    match format {
        Format::Table => write!(out, "{}", chain_row::table(name, beads, o))?,
        Format::Csv => {
            let mut w = csv::Writer::from_writer(&mut out);
            w.write_record(chain_row::header(beads))?;
            w.write_record(chain_row::fields(beads, o))?;
            w.flush()?;
        }
    }
    Ok(())
}
