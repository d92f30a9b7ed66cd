//! How [`super::JointModel`] reaches its quasi-static [`World`]: inline (each world action
//! runs inside the sub-step that asks for it: deterministic, for offline use and tests) or on
//! a thread of its own (the emulator's sub-steps never wait for a world action, which costs
//! milliseconds in a release build and up to a tenth of a second in a debug one, longer than
//! the driver's 30 ms watchdog; the result is applied at the first sub-step after it is
//! ready).

use std::sync::mpsc::{Receiver, Sender, TryRecvError, channel};
use std::thread::JoinHandle;

use dips_world::hand::ObjectPose;
use dips_world::kinematics::HandJoints;
use dips_world::world::World;

/// One world action's outcome: where the world's hand ended up toward the targets it was
/// given, and the object's pose after it.
#[derive(Debug, Clone)]
pub(crate) struct WorldResult {
    /// The targets the action was given (the emulated joints when it was asked for).
    pub(crate) targets: HandJoints,
    /// The world's joints after the action.
    pub(crate) joints: HandJoints,
    /// The object after the action.
    pub(crate) pose: ObjectPose,
}

/// The object pose of a world.
pub(crate) fn pose_of(world: &World) -> ObjectPose {
    ObjectPose {
        pose: world.object().pose(),
        coords: world.object().coords(),
    }
}

/// One world action toward `targets`; a world error as text.
fn act(world: &mut World, targets: HandJoints) -> Result<WorldResult, String> {
    world
        .step_targets(&targets)
        .map_err(|e| format!("world step: {e}"))?;
    Ok(WorldResult {
        targets,
        joints: world.joints(),
        pose: pose_of(world),
    })
}

type Outcome = Result<WorldResult, String>;

/// The world, inline or behind a thread.
#[derive(Debug)]
pub(crate) enum WorldLink {
    /// Stepped in the caller's thread.
    Inline {
        world: Box<World>,
        ready: Option<Box<Outcome>>,
    },
    /// Stepped on its own thread; at most one action in flight.
    Thread {
        to_world: Option<Sender<HandJoints>>,
        from_world: Receiver<Outcome>,
        busy: bool,
        thread: Option<JoinHandle<()>>,
    },
}

impl WorldLink {
    pub(crate) fn inline(world: Box<World>) -> WorldLink {
        WorldLink::Inline { world, ready: None }
    }

    /// The world on a thread of its own; `Err` (the world given back) when no thread starts.
    pub(crate) fn thread(world: Box<World>) -> Result<WorldLink, (Box<World>, std::io::Error)> {
        let (to_world, targets) = channel::<HandJoints>();
        let (results, from_world) = channel::<Outcome>();
        // The world goes to the thread through a channel of its own, so it can come back
        // when the thread does not start.
        let (give, take) = channel::<Box<World>>();
        let spawned = std::thread::Builder::new()
            .name("joint-model-world".into())
            .spawn(move || {
                let Ok(mut world) = take.recv() else { return };
                while let Ok(t) = targets.recv() {
                    if results.send(act(&mut world, t)).is_err() {
                        return;
                    }
                }
            });
        match spawned {
            Ok(thread) => {
                // The thread waits on `take`; it cannot have dropped it yet.
                let _ = give.send(world);
                Ok(WorldLink::Thread {
                    to_world: Some(to_world),
                    from_world,
                    busy: false,
                    thread: Some(thread),
                })
            }
            Err(e) => Err((world, e)),
        }
    }

    /// Whether a new action can be asked for.
    pub(crate) fn idle(&self) -> bool {
        match self {
            WorldLink::Inline { ready, .. } => ready.is_none(),
            WorldLink::Thread { busy, .. } => !busy,
        }
    }

    /// Ask for one action toward `targets` (call only when [`WorldLink::idle`]).
    pub(crate) fn submit(&mut self, targets: HandJoints) {
        match self {
            WorldLink::Inline { world, ready } => *ready = Some(Box::new(act(world, targets))),
            WorldLink::Thread { to_world, busy, .. } => {
                if let Some(tx) = to_world {
                    // A send fails only when the thread is gone; `poll` then reports it.
                    let _ = tx.send(targets);
                }
                *busy = true;
            }
        }
    }

    /// A finished action's outcome, if one is ready.
    pub(crate) fn poll(&mut self) -> Option<Outcome> {
        match self {
            WorldLink::Inline { ready, .. } => ready.take().map(|b| *b),
            WorldLink::Thread {
                from_world, busy, ..
            } => match from_world.try_recv() {
                Ok(r) => {
                    *busy = false;
                    Some(r)
                }
                Err(TryRecvError::Empty) => None,
                Err(TryRecvError::Disconnected) => {
                    *busy = false;
                    Some(Err("the world's thread ended".into()))
                }
            },
        }
    }
}

impl Drop for WorldLink {
    fn drop(&mut self) {
        if let WorldLink::Thread {
            to_world, thread, ..
        } = self
        {
            // Closing the channel ends the thread after its current action.
            to_world.take();
            if let Some(t) = thread.take() {
                let _ = t.join();
            }
        }
    }
}
