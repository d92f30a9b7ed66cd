//! `--shard I/N`: which demo seeds one machine of a job array generates.

use std::fmt;
use std::str::FromStr;

/// Shard `index` of `count`: the demos whose position in the seed range is `index` modulo
/// `count` (positions, not seeds, so every shard gets its share of any range).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shard {
    /// This shard, `0..count`.
    pub index: usize,
    /// Number of shards.
    pub count: usize,
}

impl Shard {
    /// The whole range on one machine.
    pub const ALL: Shard = Shard { index: 0, count: 1 };

    /// The seeds of this shard among `first..first + demos`.
    pub fn seeds(self, first: u64, demos: usize) -> Vec<u64> {
        (0..demos)
            .filter(|i| i % self.count == self.index)
            .map(|i| first + i as u64)
            .collect()
    }
}

impl fmt::Display for Shard {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

/// Why `--shard` could not be read.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error(
    "--shard {given:?}: {reason}; write I/N with 0 ≤ I < N, e.g. 0/4 (Slurm: $SLURM_ARRAY_TASK_ID/$SLURM_ARRAY_TASK_COUNT)"
)]
pub struct ShardError {
    /// What was given.
    pub given: String,
    /// What is wrong.
    pub reason: &'static str,
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
        let count: usize = n
            .trim()
            .parse()
            .map_err(|_| err("N is not a whole number"))?;
        if count == 0 {
            return Err(err("N must be at least 1"));
        }
        if index >= count {
            return Err(err("I must be below N"));
        }
        Ok(Shard { index, count })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
        assert_eq!("2/5".parse::<Shard>(), Ok(Shard { index: 2, count: 5 }));
        for bad in ["5/5", "1", "a/2", "0/0", "-1/3"] {
            let e = bad.parse::<Shard>().unwrap_err().to_string();
            assert!(e.contains("I/N"), "{bad}: {e}");
        }
    }
}
