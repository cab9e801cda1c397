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
use hertz_cradle::cli::{flag, parse_shard, BackendChoice, Cli, Command, Format};
use hertz_cradle::engine::{simulate_chain, Chain, Model, Silent, Solver};
use hertz_cradle::output::merge::merge;
use hertz_cradle::output::{row, trace::TraceWriter};
use hertz_cradle::plot;
use hertz_cradle::scene::{builtin, Precision, Scene};
use hertz_cradle::sweep::{run::Options, Sweep};
use hertz_cradle::InputError;

fn main() -> ExitCode {
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
        Command::Sweep {
            sweep,
            out,
            backend,
            resume,
            shard,
            threads,
            error_estimate,
            solver,
        } => {
            let overrides = solver.overrides()?;
            let shard = shard.as_deref().map(parse_shard).transpose()?;
            let spec = Sweep::load(&sweep)?;
            if let Some(t) = threads {
                if t == 0 {
                    return Err(flag("--threads", "0", "at least 1").into());
                }
                rayon::ThreadPoolBuilder::new()
                    .num_threads(t)
                    .build_global()?;
            }
            if let Some(dir) = out.parent().filter(|d| !d.as_os_str().is_empty()) {
                if !dir.is_dir() {
                    return Err(flag(
                        "--out",
                        &out.display().to_string(),
                        "a file in an existing directory",
                    )
                    .into());
                }
            }
            let precision = Solver::resolve(&spec.base, &overrides)?.precision;
            let backend = choose_backend(backend, precision)?;
            let backend = backend.as_ref();
            let opts = Options {
                out: out.clone(),
                resume,
                shard,
                overrides,
                command: std::env::args().collect(),
                error_estimate,
            };
            let s = hertz_cradle::sweep::run::run(&spec, &opts, backend)?;
            if s.already_complete {
                eprintln!(
                    "cradle: {} is already complete; nothing to resume",
                    out.display()
                );
            } else {
                eprintln!(
                    "cradle: {} scenes ({} ok, {} not ok) in {:.2} s, {:.0} scenes/s, backend {} ({}) -> {}",
                    s.scenes,
                    s.ok,
                    s.scenes - s.ok,
                    s.wall_s,
                    s.scenes as f64 / s.wall_s.max(1e-9),
                    backend.name(),
                    backend.adapter(),
                    out.display()
                );
            }
            Ok(())
        }
        Command::Merge { inputs, out } => {
            let n = merge(&inputs, &out)?;
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
            match (table, trace) {
                (_, Some(tr)) => plot::trace::plot(&tr, title.as_deref(), &out)?,
                (Some(t), None) => plot::heatmap::plot(
                    &t,
                    &plot::heatmap::Args {
                        x: x.unwrap_or_default(),
                        y: y.unwrap_or_default(),
                        z: z.unwrap_or_default(),
                        wheres,
                        title,
                    },
                    &out,
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
