//! Shards: `K/N` (or `slurm`, a task of a Slurm job array) and the id range
//! of shard K — contiguous ids balanced in expected cost.

use rayon::prelude::*;

use super::Sweep;
use crate::engine::Overrides;
use crate::error::{flag, InputError};

/// Scenes sampled to estimate the cost profile of a sweep for sharding.
pub const COST_SAMPLES: u64 = 65_536;

/// Parse `K/N` with 1 ≤ K ≤ N, or `slurm`: this task of a Slurm job array
/// (K = SLURM_ARRAY_TASK_ID − SLURM_ARRAY_TASK_MIN + 1, N = SLURM_ARRAY_TASK_COUNT).
///
/// ```
/// use hertz_cradle::sweep::shard::parse_shard;
/// assert_eq!(parse_shard("2/4").unwrap(), (2, 4));
/// assert!(parse_shard("5/4").is_err());
/// ```
pub fn parse_shard(s: &str) -> Result<(u64, u64), InputError> {
    if s == "slurm" {
        return slurm_shard(|k| std::env::var(k).ok());
    }
    let bad = || {
        flag(
            "--shard",
            s,
            "K/N with integers 1 ≤ K ≤ N, e.g. 2/4, or slurm",
        )
    };
    let (k, n) = s.split_once('/').ok_or_else(bad)?;
    let (k, n): (u64, u64) = (
        k.trim().parse().map_err(|_| bad())?,
        n.trim().parse().map_err(|_| bad())?,
    );
    if k == 0 || n == 0 || k > n {
        return Err(bad());
    }
    Ok((k, n))
}

/// `--shard slurm` from the job-array variables `env` gives.
pub fn slurm_shard(env: impl Fn(&str) -> Option<String>) -> Result<(u64, u64), InputError> {
    let var = |k: &str| -> Result<u64, InputError> {
        let v = env(k).ok_or_else(|| {
            flag(
                "--shard",
                "slurm",
                &format!("needs {k}: run it as a task of a Slurm job array (sbatch --array=1-N), or give K/N"),
            )
        })?;
        v.trim()
            .parse()
            .map_err(|_| flag("--shard", "slurm", &format!("{k}={v:?} is not an integer")))
    };
    let (id, count) = (var("SLURM_ARRAY_TASK_ID")?, var("SLURM_ARRAY_TASK_COUNT")?);
    let min = match env("SLURM_ARRAY_TASK_MIN") {
        Some(_) => var("SLURM_ARRAY_TASK_MIN")?,
        None => 1,
    };
    let k = (id + 1)
        .checked_sub(min)
        .filter(|k| (1..=count).contains(k));
    match k {
        Some(k) => Ok((k, count)),
        None => Err(flag(
            "--shard",
            "slurm",
            &format!("task {id} of an array of {count} from {min}: outside 1..={count}"),
        )),
    }
}

impl Sweep {
    /// The id range [lo, hi) of shard k of n (1-based): contiguous ids,
    /// balanced in expected cost (scene costs differ by orders of magnitude
    /// across a sweep). The cumulative cost is estimated from every scene, or
    /// from [`COST_SAMPLES`] evenly spaced ones (linear in between), with
    /// the model's cost (`crate::model::Model::cost`); every shard computes the same boundaries.
    pub fn shard_range(&self, shard: Option<(u64, u64)>, o: &Overrides) -> (u64, u64) {
        let total = self.total;
        let Some((k, n)) = shard else {
            return (0, total);
        };
        let samples = total.min(COST_SAMPLES);
        let ids: Vec<u64> = (0..samples)
            .map(|j| ((j as u128 * total as u128) / samples as u128) as u64)
            .collect();
        let costs: Vec<f64> = ids
            .par_iter()
            .map(|&id| self.model.cost(self.scene(id), o))
            .collect();
        // Sample j stands for ids [ids[j], ids[j+1]): cumulative cost at its start.
        let mut cum = Vec::with_capacity(ids.len() + 1);
        let mut acc = 0.0;
        cum.push(0.0);
        for (j, c) in costs.iter().enumerate() {
            let next = ids.get(j + 1).copied().unwrap_or(total);
            acc += c * (next - ids[j]) as f64;
            cum.push(acc);
        }
        // The first id where the cumulative cost reaches i/n of the total.
        let at = |i: u64| -> u64 {
            if i == 0 {
                return 0;
            }
            if i == n {
                return total;
            }
            let target = acc * i as f64 / n as f64;
            let j = cum.partition_point(|&c| c < target).clamp(1, ids.len()) - 1;
            let end = ids.get(j + 1).copied().unwrap_or(total);
            let per = costs[j].max(f64::MIN_POSITIVE);
            let id = ids[j] + ((target - cum[j]) / per).ceil().max(0.0) as u64;
            id.min(end)
        };
        let (lo, hi) = (at(k - 1), at(k));
        (lo, hi.max(lo))
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn shards_parse() {
        assert_eq!(super::parse_shard("2/4").unwrap(), (2, 4));
        for bad in ["0/4", "5/4", "2", "a/b", "1/0"] {
            assert!(super::parse_shard(bad).is_err(), "{bad}");
        }
    }
}
