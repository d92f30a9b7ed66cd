//! `--shard I/N` and `--shard auto`: which part of a batch (demo seeds, episodes) one task of a
//! job array runs, given by hand or read from the scheduler's environment.

use std::fmt;
use std::str::FromStr;

/// Shard `index` of `count`: the items whose position in the batch is `index` modulo `count`
/// (positions, not seeds, so every shard gets its share of any range).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shard {
    /// This shard, `0..count`.
    pub index: usize,
    /// Number of shards.
    pub count: usize,
}

impl Shard {
    /// The whole batch on one machine.
    pub const ALL: Shard = Shard { index: 0, count: 1 };

    /// Whether the item at `position` of the batch is this shard's.
    pub fn owns(self, position: usize) -> bool {
        position % self.count == self.index
    }

    /// The seeds of this shard among `first..first + demos`.
    pub fn seeds(self, first: u64, demos: usize) -> Vec<u64> {
        (0..demos)
            .filter(|&i| self.owns(i))
            .map(|i| first + i as u64)
            .collect()
    }

    /// This shard's items of `items`, in order.
    pub fn take<T: Clone>(self, items: &[T]) -> Vec<T> {
        items
            .iter()
            .enumerate()
            .filter(|(i, _)| self.owns(*i))
            .map(|(_, x)| x.clone())
            .collect()
    }

    /// The shard that owns position `position` of a batch split `count` ways.
    pub fn of_position(position: usize, count: usize) -> Shard {
        Shard {
            index: position % count.max(1),
            count: count.max(1),
        }
    }
}

impl fmt::Display for Shard {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

/// A shard as given: by hand, or `auto` (from the scheduler's environment).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ShardSpec {
    /// `I/N`.
    Given(Shard),
    /// `auto`: index and count from Slurm's array variables; `auto/N`: the index from the
    /// environment (Slurm, or Kubernetes' `JOB_COMPLETION_INDEX`) and the count given.
    Auto {
        /// The count given with `auto/N`.
        count: Option<usize>,
    },
}

impl Default for ShardSpec {
    fn default() -> Self {
        ShardSpec::Given(Shard::ALL)
    }
}

impl fmt::Display for ShardSpec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ShardSpec::Given(s) => s.fmt(f),
            ShardSpec::Auto { count: None } => f.write_str("auto"),
            ShardSpec::Auto { count: Some(n) } => write!(f, "auto/{n}"),
        }
    }
}

/// The scheduler variables [`ShardSpec::resolve`] reads.
pub const SHARD_ENV_VARS: [&str; 5] = [
    "SLURM_ARRAY_TASK_ID",
    "SLURM_ARRAY_TASK_COUNT",
    "SLURM_ARRAY_TASK_MIN",
    "SLURM_ARRAY_TASK_STEP",
    "JOB_COMPLETION_INDEX",
];

/// Where a resolved shard came from, for the log.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ResolvedShard {
    /// The shard.
    pub shard: Shard,
    /// How it was found (`given`, or the variables read).
    pub source: String,
}

impl ShardSpec {
    /// The shard this task runs. `auto` reads `SLURM_ARRAY_TASK_ID` (minus
    /// `SLURM_ARRAY_TASK_MIN`, divided by `SLURM_ARRAY_TASK_STEP`) and
    /// `SLURM_ARRAY_TASK_COUNT`; `auto/N` takes the count given and the index from Slurm or
    /// from `JOB_COMPLETION_INDEX` (a Kubernetes Indexed Job). `env` looks a variable up
    /// (`std::env::var` in the binary; a table in tests).
    pub fn resolve(
        self,
        env: &dyn Fn(&str) -> Option<String>,
    ) -> Result<ResolvedShard, ShardEnvError> {
        let count_given = match self {
            ShardSpec::Given(shard) => {
                return Ok(ResolvedShard {
                    shard,
                    source: "given".into(),
                });
            }
            ShardSpec::Auto { count } => count,
        };
        let number = |name: &'static str| -> Result<Option<usize>, ShardEnvError> {
            match env(name) {
                None => Ok(None),
                Some(v) => v
                    .trim()
                    .parse::<usize>()
                    .map(Some)
                    .map_err(|_| ShardEnvError::NotANumber { name, value: v }),
            }
        };
        let (index, count, source) = if let Some(id) = number("SLURM_ARRAY_TASK_ID")? {
            let min = number("SLURM_ARRAY_TASK_MIN")?.unwrap_or(0);
            let step = number("SLURM_ARRAY_TASK_STEP")?.unwrap_or(1).max(1);
            if id < min || (id - min) % step != 0 {
                return Err(ShardEnvError::Inconsistent(format!(
                    "SLURM_ARRAY_TASK_ID={id} is not on the array's grid (min {min}, step {step})"
                )));
            }
            let index = (id - min) / step;
            let count = match (count_given, number("SLURM_ARRAY_TASK_COUNT")?) {
                (Some(n), Some(m)) if n != m => {
                    return Err(ShardEnvError::CountDiffers { given: n, slurm: m });
                }
                (Some(n), _) | (None, Some(n)) => n,
                (None, None) => return Err(ShardEnvError::Missing("SLURM_ARRAY_TASK_COUNT")),
            };
            (index, count, format!("SLURM_ARRAY_TASK_ID={id}"))
        } else if let Some(index) = number("JOB_COMPLETION_INDEX")? {
            let count = count_given.ok_or(ShardEnvError::CountNeeded)?;
            (index, count, format!("JOB_COMPLETION_INDEX={index}"))
        } else {
            return Err(ShardEnvError::NoScheduler);
        };
        if count == 0 {
            return Err(ShardEnvError::Inconsistent("the shard count is 0".into()));
        }
        if index >= count {
            return Err(ShardEnvError::Inconsistent(format!(
                "{source} gives index {index}, not below the count {count}"
            )));
        }
        Ok(ResolvedShard {
            shard: Shard { index, count },
            source: format!("{source}, count {count}"),
        })
    }

    /// [`ShardSpec::resolve`] with the process's environment.
    pub fn resolve_from_env(self) -> Result<ResolvedShard, ShardEnvError> {
        self.resolve(&|name| std::env::var(name).ok())
    }
}

/// Why the shard `auto` found no shard in the environment.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ShardEnvError {
    /// Neither Slurm's nor Kubernetes' index is set.
    #[error(
        "shard auto: no job array here (neither SLURM_ARRAY_TASK_ID nor JOB_COMPLETION_INDEX is \
         set); submit it as an array (sbatch --array=0-3) or give the shard as I/N"
    )]
    NoScheduler,
    /// A variable the resolution needs is missing.
    #[error("shard auto: {0} is not set; give the count as auto/N")]
    Missing(&'static str),
    /// Kubernetes gives the index only.
    #[error(
        "shard auto: JOB_COMPLETION_INDEX gives the index only; give the count as auto/N (the \
         Job's completions)"
    )]
    CountNeeded,
    /// A variable is not a whole number.
    #[error("shard auto: {name}={value:?} is not a whole number")]
    NotANumber {
        /// The variable.
        name: &'static str,
        /// Its value.
        value: String,
    },
    /// The count given with `auto/N` is not Slurm's.
    #[error("shard auto/{given} but SLURM_ARRAY_TASK_COUNT={slurm}")]
    CountDiffers {
        /// The count given.
        given: usize,
        /// Slurm's count.
        slurm: usize,
    },
    /// The variables disagree.
    #[error("shard auto: {0}")]
    Inconsistent(String),
}

/// Why a shard (`I/N`, `auto`, `auto/N`) could not be read.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error(
    "shard {given:?}: {reason}; write I/N with 0 ≤ I < N (e.g. 0/4), auto (Slurm's \
     SLURM_ARRAY_TASK_ID and SLURM_ARRAY_TASK_COUNT) or auto/N (the index from Slurm or \
     JOB_COMPLETION_INDEX)"
)]
pub struct ShardError {
    /// What was given.
    pub given: String,
    /// What is wrong.
    pub reason: &'static str,
}

fn parse_count(s: &str, given: &str) -> Result<usize, ShardError> {
    let err = |reason| ShardError {
        given: given.to_string(),
        reason,
    };
    let count: usize = s
        .trim()
        .parse()
        .map_err(|_| err("N is not a whole number"))?;
    if count == 0 {
        return Err(err("N must be at least 1"));
    }
    Ok(count)
}

impl FromStr for Shard {
    type Err = ShardError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let err = |reason| ShardError {
            given: s.to_string(),
            reason,
        };
        let (i, n) = s.split_once('/').ok_or_else(|| err("no '/'"))?;
        let index: usize = i
            .trim()
            .parse()
            .map_err(|_| err("I is not a whole number"))?;
        let count = parse_count(n, s)?;
        if index >= count {
            return Err(err("I must be below N"));
        }
        Ok(Shard { index, count })
    }
}

impl FromStr for ShardSpec {
    type Err = ShardError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let t = s.trim();
        if t == "auto" {
            return Ok(ShardSpec::Auto { count: None });
        }
        if let Some(n) = t.strip_prefix("auto/") {
            return Ok(ShardSpec::Auto {
                count: Some(parse_count(n, s)?),
            });
        }
        s.parse().map(ShardSpec::Given)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn env<'a>(vars: &'a [(&'a str, &'a str)]) -> impl Fn(&str) -> Option<String> + 'a {
        move |name| {
            vars.iter()
                .find(|(k, _)| *k == name)
                .map(|(_, v)| v.to_string())
        }
    }

    #[test]
    fn shards_partition_the_seeds() {
        let all: Vec<u64> = (0..4)
            .flat_map(|i| Shard { index: i, count: 4 }.seeds(100, 10))
            .collect();
        let mut sorted = all.clone();
        sorted.sort_unstable();
        assert_eq!(sorted, (100..110).collect::<Vec<_>>());
        assert_eq!(
            Shard { index: 1, count: 4 }.seeds(100, 10),
            vec![101, 105, 109]
        );
        assert_eq!(Shard { index: 1, count: 3 }.take(&[0, 1, 2, 3, 4]), [1, 4]);
        assert_eq!("2/5".parse::<Shard>(), Ok(Shard { index: 2, count: 5 }));
        for bad in ["5/5", "1", "a/2", "0/0", "-1/3", "auto/0", "auto/x"] {
            let e = bad.parse::<ShardSpec>().unwrap_err().to_string();
            assert!(e.contains("I/N") && e.contains("auto"), "{bad}: {e}");
        }
    }

    #[test]
    fn auto_reads_slurm_and_kubernetes() {
        let auto = ShardSpec::Auto { count: None };
        let s = auto
            .resolve(&env(&[
                ("SLURM_ARRAY_TASK_ID", "2"),
                ("SLURM_ARRAY_TASK_COUNT", "4"),
            ]))
            .unwrap();
        assert_eq!(s.shard, Shard { index: 2, count: 4 });
        // An array 1-4 numbers its tasks from 1; one of step 2 (0-6:2) skips.
        let s = auto
            .resolve(&env(&[
                ("SLURM_ARRAY_TASK_ID", "4"),
                ("SLURM_ARRAY_TASK_COUNT", "4"),
                ("SLURM_ARRAY_TASK_MIN", "1"),
            ]))
            .unwrap();
        assert_eq!(s.shard, Shard { index: 3, count: 4 });
        let s = auto
            .resolve(&env(&[
                ("SLURM_ARRAY_TASK_ID", "6"),
                ("SLURM_ARRAY_TASK_COUNT", "4"),
                ("SLURM_ARRAY_TASK_STEP", "2"),
            ]))
            .unwrap();
        assert_eq!(s.shard, Shard { index: 3, count: 4 });
        let k8s = ShardSpec::Auto { count: Some(3) }
            .resolve(&env(&[("JOB_COMPLETION_INDEX", "1")]))
            .unwrap();
        assert_eq!(k8s.shard, Shard { index: 1, count: 3 });
        assert_eq!(
            "auto/3".parse::<ShardSpec>(),
            Ok(ShardSpec::Auto { count: Some(3) })
        );
        let given = "1/2"
            .parse::<ShardSpec>()
            .unwrap()
            .resolve(&env(&[]))
            .unwrap();
        assert_eq!(given.shard, Shard { index: 1, count: 2 });
    }

    #[test]
    fn a_missing_or_inconsistent_environment_is_named() {
        let auto = ShardSpec::Auto { count: None };
        let e = |vars: &[(&str, &str)], spec: ShardSpec| spec.resolve(&env(vars)).unwrap_err();
        assert_eq!(e(&[], auto), ShardEnvError::NoScheduler);
        assert_eq!(
            e(&[("SLURM_ARRAY_TASK_ID", "0")], auto),
            ShardEnvError::Missing("SLURM_ARRAY_TASK_COUNT")
        );
        assert_eq!(
            e(&[("JOB_COMPLETION_INDEX", "0")], auto),
            ShardEnvError::CountNeeded
        );
        let msg = e(
            &[
                ("SLURM_ARRAY_TASK_ID", "4"),
                ("SLURM_ARRAY_TASK_COUNT", "4"),
            ],
            auto,
        )
        .to_string();
        assert!(msg.contains("not below the count 4"), "{msg}");
        let msg = e(
            &[
                ("SLURM_ARRAY_TASK_ID", "1"),
                ("SLURM_ARRAY_TASK_COUNT", "4"),
            ],
            ShardSpec::Auto { count: Some(2) },
        )
        .to_string();
        assert!(msg.contains("auto/2") && msg.contains("=4"), "{msg}");
        let msg = e(
            &[
                ("SLURM_ARRAY_TASK_ID", "x"),
                ("SLURM_ARRAY_TASK_COUNT", "4"),
            ],
            auto,
        )
        .to_string();
        assert!(msg.contains("SLURM_ARRAY_TASK_ID=\"x\""), "{msg}");
    }
}
