//! One shard's pending items on a thread pool, the one runner of the batch commands
//! (`dips datagen`, `dips eval`): a `resuming: …` line when some items are done, a
//! [`Progress`], `jobs` workers taking items from one queue on a pool of
//! `jobs × threads_per_job` threads (so the work inside an item, CSVTO's particles or a model
//! call's batch, uses the cores its job has), and a stop at the first failure: the items in
//! flight finish, no new one starts, and the failure is returned. What a finished shard
//! records is [`ShardOutcome::record`], written only when every item of the shard is done.

use std::path::Path;
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

use serde::Serialize;

use crate::progress::{Progress, ProgressMode, note_before};
use crate::record::{BatchError, ShardRecord, write_record};
use crate::shard::Shard;

/// How a shard's items run.
#[derive(Debug, Clone)]
pub struct ShardRun {
    /// The progress bar's label (`datagen card shard 1/2`).
    pub label: String,
    /// What an item is called, singular and plural (`("demo", "demos")`).
    pub units: (&'static str, &'static str),
    /// Where progress goes.
    pub progress: ProgressMode,
    /// Items run at once (the workers).
    pub jobs: usize,
    /// Threads of each worker: the pool has `jobs × threads_per_job`.
    pub threads_per_job: usize,
    /// Run at most this many of the pending items (tests simulate a kill with it); a run cut
    /// short has not finished its shard.
    pub stop_after: Option<usize>,
}

/// What a shard's run did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ShardOutcome {
    /// Items run by this call.
    pub ran: usize,
    /// Items of the shard that were done before it (resumed).
    pub skipped: usize,
    /// Items that finished with a note (a failure recorded as a result, say).
    pub noted: usize,
    /// Items in the shard.
    pub total: usize,
    /// Wall time of the run (s).
    pub seconds: f64,
}

impl ShardOutcome {
    /// Whether every item of the shard is done (not when `stop_after` cut the run short).
    pub fn complete(&self) -> bool {
        self.ran + self.skipped == self.total
    }

    /// Record that `shard` finished in `dir` with `report` (`shards/shard-I-of-N.json`), only
    /// when the shard is [complete](Self::complete); `None` otherwise.
    pub fn record(
        &self,
        dir: &Path,
        shard: Shard,
        report: &impl Serialize,
    ) -> Result<Option<ShardRecord>, BatchError> {
        if !self.complete() {
            return Ok(None);
        }
        write_record(dir, shard, self.seconds, report).map(Some)
    }
}

/// Why a shard's run stopped.
#[derive(Debug, thiserror::Error)]
pub enum RunShardError<E> {
    /// The worker threads cannot be started.
    #[error("thread pool: {0}")]
    ThreadPool(rayon::ThreadPoolBuildError),
    /// The first item that failed (the items in flight with it finished, no new one started).
    #[error(transparent)]
    Item(E),
}

/// Stack of each worker thread: a work item may build a large value on its stack before it
/// boxes it (a host-size planner, `dips_planning::sized::HostSession`, is about 2.4 MB; a
/// debug build copies it more than once). Only the pages touched are committed.
pub const WORKER_STACK_BYTES: usize = 64 << 20;

/// Run `pending`, the unfinished items of a shard of which `skipped` are done, as `run` says:
/// `work` runs one item and answers `Ok(None)`, `Ok(Some(note))` (the note is shown above the
/// progress and counted in [`ShardOutcome::noted`]) or the error that stops the run; `name`
/// names an item in the progress (`seed 3`).
pub fn run_shard<T, E, N, W>(
    run: &ShardRun,
    mut pending: Vec<T>,
    skipped: usize,
    name: N,
    work: W,
) -> Result<ShardOutcome, RunShardError<E>>
where
    T: Send,
    E: Send,
    N: Fn(&T) -> String + Sync,
    W: Fn(&T) -> Result<Option<String>, E> + Sync,
{
    let total = skipped + pending.len();
    if let Some(n) = run.stop_after {
        pending.truncate(n);
    }
    if skipped > 0 {
        note_before(
            run.progress,
            &format!(
                "resuming: {skipped} of this shard's {total} {} are done",
                run.units.1
            ),
        );
    }
    let progress = Progress::new(
        run.label.clone(),
        pending.len() as u64,
        run.units,
        run.progress,
    );
    let started = Instant::now();
    let noted = AtomicUsize::new(0);
    let failure: Mutex<Option<E>> = Mutex::new(None);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(run.jobs * run.threads_per_job)
        .stack_size(WORKER_STACK_BYTES)
        .build()
        .map_err(RunShardError::ThreadPool)?;
    let ran = pending.len();
    let queue = Mutex::new(pending.into_iter());
    pool.scope(|scope| {
        for _ in 0..run.jobs {
            scope.spawn(|_| {
                loop {
                    if failure.lock().map(|f| f.is_some()).unwrap_or(true) {
                        return;
                    }
                    let next = queue.lock().ok().and_then(|mut q| q.next());
                    let Some(item) = next else { return };
                    match work(&item) {
                        Ok(note) => {
                            if let Some(note) = note {
                                noted.fetch_add(1, Ordering::Relaxed);
                                progress.note(&note);
                            }
                            progress.item_done(Some(&name(&item)));
                        }
                        Err(e) => {
                            if let Ok(mut f) = failure.lock() {
                                f.get_or_insert(e);
                            }
                        }
                    }
                }
            });
        }
    });
    progress.finish();
    if let Some(e) = failure.into_inner().ok().flatten() {
        return Err(RunShardError::Item(e));
    }
    Ok(ShardOutcome {
        ran,
        skipped,
        noted: noted.into_inner(),
        total,
        seconds: started.elapsed().as_secs_f64(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(jobs: usize, stop_after: Option<usize>) -> ShardRun {
        ShardRun {
            label: "test".into(),
            units: ("item", "items"),
            progress: ProgressMode::Hidden,
            jobs,
            threads_per_job: 2,
            stop_after,
        }
    }

    #[test]
    fn every_item_runs_once_and_notes_are_counted() {
        let seen = Mutex::new(Vec::new());
        let out = run_shard(
            &run(3, None),
            (0..10).collect(),
            2,
            |i| format!("item {i}"),
            |&i| -> Result<_, ()> {
                assert_eq!(rayon::current_num_threads(), 6);
                seen.lock().unwrap().push(i);
                Ok((i % 3 == 0).then(|| format!("{i} noted")))
            },
        )
        .unwrap();
        let mut seen = seen.into_inner().unwrap();
        seen.sort();
        assert_eq!(seen, (0..10).collect::<Vec<_>>());
        assert_eq!((out.ran, out.skipped, out.noted, out.total), (10, 2, 4, 12));
        assert!(out.complete());
    }

    #[test]
    fn a_cut_short_run_is_not_complete_and_leaves_no_record() {
        let out = run_shard(
            &run(2, Some(1)),
            vec![1, 2, 3],
            1,
            |i| i.to_string(),
            |_| -> Result<_, ()> { Ok(None) },
        )
        .unwrap();
        assert_eq!((out.ran, out.skipped, out.total), (1, 1, 4));
        assert!(!out.complete());
        let dir = std::env::temp_dir().join(format!("dips-batch-run-{}", std::process::id()));
        assert_eq!(out.record(&dir, Shard::ALL, &()).unwrap(), None);
        assert!(!dir.exists());
    }

    #[test]
    fn the_first_failure_stops_the_run() {
        let started = AtomicUsize::new(0);
        let e = run_shard(
            &run(1, None),
            (0..5).collect(),
            0,
            |i| i.to_string(),
            |&i| {
                started.fetch_add(1, Ordering::Relaxed);
                if i == 1 { Err(i) } else { Ok(None) }
            },
        )
        .unwrap_err();
        assert!(matches!(e, RunShardError::Item(1)), "{e:?}");
        // One worker: nothing after the failing item started.
        assert_eq!(started.into_inner(), 2);
    }
}
