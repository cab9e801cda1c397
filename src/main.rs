//! `cradle`: the command-line front end. `run()` does the work; `main` prints
//! the whole error chain and exits 2 for bad input, 1 for anything else.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::process::ExitCode;

use anyhow::Context;
use clap::Parser;

use hertz_cradle::backend::cpu::Cpu;
use hertz_cradle::backend::gpu::{find_adapter, Gpu, Want};
use hertz_cradle::backend::Backend;
use hertz_cradle::cli::{flag, BackendChoice, Cli, Command, Format};
use hertz_cradle::config::SweepConfig;
use hertz_cradle::engine::{simulate_chain, Chain, Model, Silent, Solver};
use hertz_cradle::output::guard;
use hertz_cradle::output::lock::OutputLock;
use hertz_cradle::output::merge::merge;
use hertz_cradle::output::{row, trace::TraceWriter};
use hertz_cradle::plot;
use hertz_cradle::scene::{builtin, Precision, Scene};
use hertz_cradle::sweep::{run::Options, Sweep};
use hertz_cradle::InputError;

/// Largest trace `cradle run --trace` writes (bytes); refused before running.
const MAX_TRACE_BYTES: f64 = 1e9;
/// Characters of one trace number (`-1.2345678901234567e-5,`).
const TRACE_BYTES_PER_NUMBER: f64 = 24.0;

fn main() -> ExitCode {
    hertz_cradle::backend::gpu::quiet_mesa_without_session();
    let cli = Cli::parse();
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            if is_broken_pipe(&e) {
                return ExitCode::SUCCESS;
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

/// `auto`: a hardware GPU that can run `precision`, else the CPU (said on
/// stderr); `gpu`: any adapter, software ones included, or an error.
fn choose_backend(choice: BackendChoice, precision: Precision) -> anyhow::Result<Box<dyn Backend>> {
    let want = match choice {
        BackendChoice::Cpu => return Ok(Box::new(Cpu)),
        BackendChoice::Auto => Want::Hardware,
        BackendChoice::Gpu => Want::Any,
    };
    let Some(adapter) = find_adapter(want) else {
        if choice == BackendChoice::Gpu {
            return Err(flag("--backend", "gpu", "no GPU adapter found (not even a software one such as Mesa lavapipe); use --backend cpu").into());
        }
        eprintln!(
            "cradle: no hardware GPU found; running on the CPU ({})",
            Cpu.adapter()
        );
        return Ok(Box::new(Cpu));
    };
    let gpu = Gpu::new(&adapter)?;
    if precision == Precision::F64 && !gpu.has_f64() {
        if choice == BackendChoice::Gpu {
            return Err(flag(
                "--backend",
                "gpu",
                &format!(
                    "{} has no 64-bit floats (SHADER_F64): add --precision f32",
                    gpu.adapter()
                ),
            )
            .into());
        }
        eprintln!("cradle: {} has no 64-bit floats; running f64 on the CPU ({}); --precision f32 would use the GPU", gpu.adapter(), Cpu.adapter());
        return Ok(Box::new(Cpu));
    }
    eprintln!("cradle: backend gpu: {}", gpu.adapter());
    Ok(Box::new(gpu))
}

fn is_broken_pipe(e: &anyhow::Error) -> bool {
    e.chain().any(|c| {
        c.downcast_ref::<std::io::Error>()
            .is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe)
    })
}

fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Sweep(args) => {
            // Every check (flags, the sweep file, the output path, flags
            // against the file) before any work or any GPU start-up.
            let cfg = SweepConfig::from_args(&args)?;
            if let Some(t) = cfg.threads {
                rayon::ThreadPoolBuilder::new()
                    .num_threads(t)
                    .build_global()?;
            }
            let backend = choose_backend(cfg.backend, cfg.precision)?;
            let backend = backend.as_ref();
            let opts = Options {
                out: cfg.out.clone(),
                resume: cfg.resume,
                shard: cfg.shard,
                overrides: cfg.overrides.clone(),
                command: std::env::args().collect(),
                error_estimate: cfg.error_estimate,
            };
            let s = hertz_cradle::sweep::run::run(&cfg.sweep, &opts, backend)?;
            let out = cfg.out_given.display();
            if s.already_complete {
                eprintln!("cradle: {out} is already complete; nothing to resume");
            } else {
                eprintln!(
                    "cradle: {} scenes ({} ok, {} not ok) in {:.2} s, {:.0} scenes/s, backend {} ({}) -> {out}",
                    s.scenes,
                    s.ok,
                    s.scenes - s.ok,
                    s.wall_s,
                    s.scenes as f64 / s.wall_s.max(1e-9),
                    backend.name(),
                    backend.adapter(),
                );
            }
            Ok(())
        }
        Command::Merge { inputs, out } => {
            let target = guard::output(
                "--out",
                &out,
                &inputs,
                &[".partial", ".json", ".json.tmp", ".lock"],
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
        Command::Plot {
            table,
            trace,
            x,
            y,
            z,
            wheres,
            title,
            out,
        } => {
            let input = table.iter().chain(&trace).cloned().collect::<Vec<_>>();
            let out_path = guard::output("--out", &out, &input, &[])?;
            let out = &out_path;
            match (table, trace) {
                (_, Some(tr)) => plot::trace::plot(&tr, title.as_deref(), out)?,
                (Some(t), None) => plot::heatmap::plot(
                    &t,
                    &plot::heatmap::Args {
                        x: x.unwrap_or_default(),
                        y: y.unwrap_or_default(),
                        z: z.unwrap_or_default(),
                        wheres,
                        title,
                    },
                    out,
                )?,
                (None, None) => unreachable!("clap requires a table or --trace"),
            }
            eprintln!("cradle: wrote {}", out.display());
            Ok(())
        }
        Command::Slurm {
            sweep,
            shards,
            out,
            dir,
            partition,
            gpus_per_task,
            cpus_per_task,
            time,
            cradle,
            solver,
        } => {
            // Check everything now, not on the cluster.
            let spec = Sweep::load(&sweep)?;
            let overrides = solver.overrides()?;
            Solver::resolve(&spec.base, &overrides)?;
            if shards == 0 || shards > spec.total {
                return Err(flag(
                    "--shards",
                    &shards.to_string(),
                    &format!("1 ..= {} (the sweep's scenes)", spec.total),
                )
                .into());
            }
            let stem = sweep
                .file_stem()
                .unwrap_or_default()
                .to_string_lossy()
                .to_string();
            let plan = hertz_cradle::slurm::Plan {
                out: out.unwrap_or_else(|| format!("{stem}.csv").into()),
                dir: dir.unwrap_or_else(|| format!("slurm-{stem}").into()),
                sweep,
                shards,
                partition,
                gpus_per_task,
                cpus_per_task,
                time,
                cradle: match cradle {
                    Some(c) => c,
                    None => std::env::current_exe()?,
                },
                flags: solver.args(),
            };
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
        } => {
            let sc = Scene::load(&scene)?;
            let solver = Solver::resolve(&sc, &solver.overrides()?)?;
            let chain = Chain::from_scene(&sc)
                .map_err(|e| anyhow::Error::new(e).context(format!("scene {scene}")))?;
            if let Some(why) = solver.model.unsupported(&chain) {
                return Err(flag("--model", solver.model.name(), &why).into());
            }
            if trace.is_some() && solver.model != Model::Hertz {
                return Err(flag(
                    "--trace",
                    solver.model.name(),
                    "a trajectory of the hertz model only (the others are instantaneous)",
                )
                .into());
            }
            let outcome = match trace {
                None => simulate_chain(&chain, &solver, &mut Silent),
                Some(path) => {
                    let every = match trace_dt {
                        Some(d) if d.is_finite() && d > 0.0 => d,
                        Some(d) => {
                            return Err(flag("--trace-dt", &d.to_string(), "a time > 0 (s)").into())
                        }
                        // A pendulum: 400 rows per swing; a free line: 20 per contact.
                        None if chain.is_pendulum() => {
                            std::f64::consts::TAU / chain.omega() / 400.0
                        }
                        None => chain.time_scale().map_or(1e-6, |tc| tc / 20.0),
                    };
                    let inputs: Vec<std::path::PathBuf> = std::path::Path::new(&scene)
                        .exists()
                        .then(|| scene.clone().into())
                        .into_iter()
                        .collect();
                    let path = guard::output("--trace", &path, &inputs, &[])?;
                    // The trace's size, known before it is written: the run's
                    // end time from a silent run (one scene: milliseconds).
                    let t_end = simulate_chain(&chain, &solver, &mut Silent).t_end;
                    let row_bytes = (1 + 2 * chain.n_balls) as f64 * TRACE_BYTES_PER_NUMBER;
                    let bytes = (t_end / every + 2.0) * row_bytes;
                    if bytes.is_nan() || bytes > MAX_TRACE_BYTES {
                        return Err(flag(
                            "--trace-dt",
                            &format!("{every:e}"),
                            &format!(
                                "the run lasts {t_end:.4e} s: {:.0} rows, about {:.1} GB of trace (at most {:.0} GB); use --trace-dt ≥ {:.1e}",
                                t_end / every,
                                bytes / 1e9,
                                MAX_TRACE_BYTES / 1e9,
                                t_end * row_bytes / (MAX_TRACE_BYTES - 2.0 * row_bytes)
                            ),
                        )
                        .into());
                    }
                    let file = File::create(&path)
                        .with_context(|| format!("cannot create trace file {}", path.display()))?;
                    let mut tw = TraceWriter::new(BufWriter::new(file), &chain, every)?;
                    let o = simulate_chain(&chain, &solver, &mut tw);
                    tw.finish()
                        .with_context(|| format!("writing {}", path.display()))?;
                    o
                }
            };
            let mut out = std::io::stdout().lock();
            match format {
                Format::Table => write!(
                    out,
                    "{}",
                    row::table(
                        &scene,
                        chain.v_in(),
                        &sc.velocity,
                        &outcome,
                        chain.is_pendulum()
                    )
                )?,
                Format::Csv => {
                    let mut w = csv::Writer::from_writer(&mut out);
                    let shape = row::Shape {
                        width: sc.n,
                        pendulum: chain.is_pendulum(),
                    };
                    w.write_record(row::header(&[], shape))?;
                    w.write_record(row::fields(0, &[], &outcome, shape))?;
                    w.flush()?;
                }
            }
            Ok(())
        }
    }
}
