//! `cradle slurm`: a sweep as a Slurm job array. Writes three scripts into a
//! directory, every path in them absolute:
//!
//! - `array.sbatch`: one task per shard, `cradle sweep … --shard K/N --resume`
//!   into `parts/shard-K-of-N.csv` (`.parquet` when the merged table is
//!   Parquet; a task that is resubmitted continues where it stopped; one
//!   that finished is not redone);
//! - `merge.sbatch`: runs after every task has ended (`afterany`), checks that
//!   every shard is complete (naming the missing ones and how to resubmit
//!   them) and `cradle merge`s them, which refuses missing or repeated ids;
//! - `submit.sh`: submits both, the merge depending on the array.
//!
//! The shard is given as `$SLURM_ARRAY_TASK_ID/N` rather than `slurm`, so that
//! `sbatch --array=K array.sbatch` reruns shard K alone with the same layout.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};

use crate::choice::Choice;
use crate::cli::SlurmArgs;
use crate::error::flag;
use crate::output::guard;
use crate::output::partial::COMPANIONS;
use crate::output::TableKind;
use crate::sweep::Sweep;

/// A checked `cradle slurm`: everything a task would refuse is refused now,
/// not on the cluster (flags against the file, the merged output's path,
/// the solver, the shard count).
pub fn plan(a: &SlurmArgs) -> Result<Plan> {
    let spec = Sweep::load(&a.sweep)?;
    let overrides = a.solver.settings().overrides()?;
    spec.check_overrides(&overrides)?;
    crate::engine::Solver::resolve(&spec.base, &overrides)?;
    if let Some(o) = &a.out {
        guard::output("--out", o, &spec.inputs, COMPANIONS)?;
        // The shards are written in the merged table's format (`cradle
        // merge` joins parts of one format into that format): a name that
        // says none would be refused by the merge, after the whole array.
        if TableKind::from_extension(o).is_none() {
            return Err(flag(
                "--out",
                &o.display().to_string(),
                "a name ending in .csv or .parquet (.pq): the merged table's format, and its shards'",
            )
            .into());
        }
    }
    if a.shards == 0 || a.shards > spec.total {
        return Err(flag(
            "--shards",
            &a.shards.to_string(),
            &format!("1 ..= {} (the sweep's scenes)", spec.total),
        )
        .into());
    }
    check_flags(a)?;
    let stem = a
        .sweep
        .file_stem()
        .unwrap_or_default()
        .to_string_lossy()
        .to_string();
    Ok(Plan {
        out: a
            .out
            .clone()
            .unwrap_or_else(|| format!("{stem}.csv").into()),
        dir: a
            .dir
            .clone()
            .unwrap_or_else(|| format!("slurm-{stem}").into()),
        sweep: a.sweep.clone(),
        shards: a.shards,
        partition: a.partition.clone(),
        gpus_per_task: a.gpus_per_task,
        cpus_per_task: a.cpus_per_task,
        time: a.time.clone(),
        cradle: match &a.cradle {
            Some(c) => c.clone(),
            None => std::env::current_exe()?,
        },
        flags: a.solver.args(),
    })
}

/// The job-script flags, as Slurm would read them: nothing may end up in a
/// script as a setting that does nothing, or as an extra `#SBATCH` line.
fn check_flags(a: &SlurmArgs) -> Result<(), crate::InputError> {
    if a.cpus_per_task == Some(0) {
        return Err(flag(
            "--cpus-per-task",
            "0",
            "a whole number ≥ 1 (the CPUs each task's sweep runs on)",
        ));
    }
    if let Some(t) = &a.time {
        if !slurm_time(t) {
            return Err(flag(
                "--time",
                &format!("{t:?}"),
                "a Slurm time limit: minutes, MM:SS, HH:MM:SS, D-HH, D-HH:MM, D-HH:MM:SS, or UNLIMITED",
            ));
        }
    }
    if let Some(p) = &a.partition {
        let ok = |c: char| c.is_ascii_alphanumeric() || "_.-,".contains(c);
        if p.is_empty() || !p.chars().all(ok) {
            return Err(flag(
                "--partition",
                &format!("{p:?}"),
                "a partition name (or a comma-separated list): letters, digits, _ . - only",
            ));
        }
    }
    Ok(())
}

/// Whether `t` is one of Slurm's `--time` formats.
fn slurm_time(t: &str) -> bool {
    if matches!(t, "UNLIMITED" | "INFINITE" | "unlimited" | "infinite") {
        return true;
    }
    let num = |s: &str| !s.is_empty() && s.len() <= 6 && s.bytes().all(|b| b.is_ascii_digit());
    let (days, rest) = match t.split_once('-') {
        Some((d, r)) => (Some(d), r),
        None => (None, t),
    };
    if days.is_some_and(|d| !num(d)) {
        return false;
    }
    let parts: Vec<&str> = rest.split(':').collect();
    // MM, MM:SS, HH:MM:SS; after a day count: HH, HH:MM, HH:MM:SS.
    parts.iter().all(|p| num(p)) && (1..=3).contains(&parts.len())
}

pub struct Plan {
    pub sweep: PathBuf,
    pub shards: u64,
    pub out: PathBuf,
    pub dir: PathBuf,
    pub partition: Option<String>,
    pub gpus_per_task: u32,
    pub cpus_per_task: Option<u32>,
    pub time: Option<String>,
    pub cradle: PathBuf,
    /// Solver flags passed to every shard.
    pub flags: Vec<String>,
}

/// A word for a POSIX shell, single-quoted.
pub fn quote(s: &str) -> String {
    format!("'{}'", s.replace('\'', r"'\''"))
}

fn q(p: &Path) -> String {
    quote(&p.display().to_string())
}

fn absolute(p: &Path) -> Result<PathBuf> {
    std::path::absolute(p).with_context(|| format!("cannot resolve {}", p.display()))
}

/// The three scripts' texts: (array.sbatch, merge.sbatch, submit.sh).
/// Long (~120 lines) on purpose: mostly the scripts' own text, read as
/// templates.
pub fn scripts(p: &Plan) -> Result<(String, String, String)> {
    let (dir, sweep, out, cradle) = (
        absolute(&p.dir)?,
        absolute(&p.sweep)?,
        absolute(&p.out)?,
        absolute(&p.cradle)?,
    );
    let n = p.shards;
    let stem = sweep
        .file_stem()
        .unwrap_or_default()
        .to_string_lossy()
        .to_string();
    // The shards' format is the merged table's (`plan` refused any other name).
    let ext = TableKind::from_extension(&out)
        .unwrap_or(TableKind::Csv)
        .name();
    let part = |k: &str| dir.join("parts").join(format!("shard-{k}-of-{n}.{ext}"));
    let mut a = String::new();
    writeln!(a, "#!/bin/bash")?;
    writeln!(
        a,
        "# A cradle sweep as a Slurm job array: shard K of {n} per task."
    )?;
    writeln!(
        a,
        "# Resubmit one shard alone: sbatch --array=K {}",
        q(&dir.join("array.sbatch"))
    )?;
    writeln!(a, "#SBATCH --job-name={}", quote(&format!("cradle-{stem}")))?;
    writeln!(a, "#SBATCH --array=1-{n}")?;
    writeln!(
        a,
        "#SBATCH --output={}",
        q(&dir.join("logs").join("shard-%a.out"))
    )?;
    if let Some(part) = &p.partition {
        writeln!(a, "#SBATCH --partition={}", quote(part))?;
    }
    if let Some(t) = &p.time {
        writeln!(a, "#SBATCH --time={}", quote(t))?;
    }
    if p.gpus_per_task > 0 {
        writeln!(a, "#SBATCH --gres=gpu:{}", p.gpus_per_task)?;
    }
    if let Some(c) = p.cpus_per_task {
        writeln!(a, "#SBATCH --cpus-per-task={c}")?;
    }
    writeln!(a, "set -euo pipefail")?;
    writeln!(a, "K=\"$SLURM_ARRAY_TASK_ID\"")?;
    let backend = if p.gpus_per_task > 0 { "gpu" } else { "auto" };
    let threads = p
        .cpus_per_task
        .map_or(String::new(), |c| format!(" --threads {c}"));
    let flags: String = p.flags.iter().map(|f| format!(" {}", quote(f))).collect();
    writeln!(
        a,
        "exec {} sweep {} --out {}\"$K\"-of-{n}.{ext} --shard \"$K\"/{n} --resume --backend {backend}{threads}{flags}",
        q(&cradle),
        q(&sweep),
        q(&dir.join("parts").join("shard-"))
    )?;

    let mut m = String::new();
    writeln!(m, "#!/bin/bash")?;
    writeln!(m, "# Merge the {n} shards once every array task has ended.")?;
    writeln!(
        m,
        "#SBATCH --job-name={}",
        quote(&format!("cradle-{stem}-merge"))
    )?;
    writeln!(
        m,
        "#SBATCH --output={}",
        q(&dir.join("logs").join("merge.out"))
    )?;
    if let Some(part) = &p.partition {
        writeln!(m, "#SBATCH --partition={}", quote(part))?;
    }
    writeln!(m, "set -euo pipefail")?;
    writeln!(m, "missing=()")?;
    writeln!(m, "for k in $(seq 1 {n}); do")?;
    writeln!(
        m,
        "  [ -f {}\"$k\"-of-{n}.{ext} ] || missing+=(\"$k\")",
        q(&dir.join("parts").join("shard-"))
    )?;
    writeln!(m, "done")?;
    writeln!(m, "if [ ${{#missing[@]}} -gt 0 ]; then")?;
    writeln!(
        m,
        "  echo \"cradle: shards not complete: ${{missing[*]}}. Resubmit each (it resumes): sbatch --array=K {}; then: sbatch {}\" >&2",
        dir.join("array.sbatch").display(),
        dir.join("merge.sbatch").display()
    )?;
    writeln!(m, "  exit 1")?;
    writeln!(m, "fi")?;
    let parts: String = (1..=n)
        .map(|k| format!(" {}", q(&part(&k.to_string()))))
        .collect();
    writeln!(m, "exec {} merge{parts} --out {}", q(&cradle), q(&out))?;

    let mut s = String::new();
    writeln!(s, "#!/bin/bash")?;
    writeln!(
        s,
        "# Submit the sweep {} as {n} array tasks, then the merge into {}.",
        sweep.display(),
        out.display()
    )?;
    writeln!(s, "set -euo pipefail")?;
    writeln!(
        s,
        "array=$(sbatch --parsable {})",
        q(&dir.join("array.sbatch"))
    )?;
    writeln!(s, "array=${{array%%;*}}")?;
    writeln!(
        s,
        "merge=$(sbatch --parsable --dependency=afterany:\"$array\" {})",
        q(&dir.join("merge.sbatch"))
    )?;
    writeln!(s, "merge=${{merge%%;*}}")?;
    writeln!(s, "echo \"$array $merge\"")?;
    Ok((a, m, s))
}

/// Write the scripts (and the `parts/`, `logs/` directories); returns their paths.
pub fn write(p: &Plan) -> Result<Vec<PathBuf>> {
    use std::os::unix::fs::PermissionsExt;
    for d in ["parts", "logs"] {
        let dir = p.dir.join(d);
        std::fs::create_dir_all(&dir).map_err(|e| crate::InputError::Data {
            path: dir.clone(),
            what: format!("cannot create this directory ({e}): give --dir a place you can write"),
        })?;
    }
    let (a, m, s) = scripts(p)?;
    let mut paths = vec![];
    // Each script written beside its name, executable, synced and renamed
    // over it (output::publish): a kill or a full disk never leaves half a
    // script for sbatch.
    for (name, text) in [("array.sbatch", a), ("merge.sbatch", m), ("submit.sh", s)] {
        let path = p.dir.join(name);
        crate::output::publish::write_with(&path, |w| {
            use std::io::Write;
            w.get_ref()
                .set_permissions(std::fs::Permissions::from_mode(0o755))
                .and_then(|_| w.write_all(text.as_bytes()))
                .with_context(|| format!("cannot write {}", path.display()))
        })?;
        paths.push(path);
    }
    Ok(paths)
}

#[cfg(test)]
mod tests {
    #[test]
    fn slurm_times() {
        for ok in [
            "30",
            "90:00",
            "12:00:00",
            "2-0",
            "2-12:30",
            "1-00:00:00",
            "UNLIMITED",
        ] {
            assert!(super::slurm_time(ok), "{ok}");
        }
        for bad in [
            "",
            "1h",
            "12:00:00\n#SBATCH --x",
            "-1",
            "1:2:3:4",
            "a-1",
            "1--2",
            " 30",
        ] {
            assert!(!super::slurm_time(bad), "{bad:?}");
        }
    }
}
