//! Many whisker states stepped against one shared model, in parallel.
//!
//! Every state owns its random stream, so the result is bit-for-bit the same whatever the number
//! of threads: work is split between threads, never the random numbers. Where nothing but base
//! motion and random forces act, states are stepped [`LANES`] at a time in lanes
//! ([`step_group`]), each to the same bits as alone.

use crate::chain::Model;
use crate::dynamics::{step_group, Inputs, LaneWorkspace, State, Stepper, Workspace, LANES};
use crate::error::Result;
use rayon::prelude::*;
use std::cell::RefCell;

thread_local! {
    /// Workspaces kept between parallel calls on this thread (a call makes one per rayon split,
    /// which for a particle filter is thousands of allocations per second otherwise).
    static SPARE: RefCell<Vec<Box<Workspace>>> = const { RefCell::new(Vec::new()) };
    /// The same for lane groups.
    static SPARE_LANES: RefCell<Vec<Box<LaneWorkspace>>> = const { RefCell::new(Vec::new()) };
}

/// Most workspaces of each kind a thread keeps.
const SPARE_MAX: usize = 4;

/// Scratch that a thread keeps spares of between parallel calls.
trait Spare: Sized + 'static {
    /// This thread's spares (boxed: a lent scratch is moved into and out of rayon's closures,
    /// which would otherwise copy all of it each time).
    const POOL: &'static std::thread::LocalKey<RefCell<Vec<Box<Self>>>>;
    /// Scratch for `model`.
    fn new(model: &Model) -> Self;
    /// Whether this scratch serves `model` (its segment count).
    fn serves(&self, model: &Model) -> bool;
}

impl Spare for Workspace {
    const POOL: &'static std::thread::LocalKey<RefCell<Vec<Box<Self>>>> = &SPARE;
    fn new(model: &Model) -> Self {
        Workspace::new(model)
    }
    fn serves(&self, model: &Model) -> bool {
        self.n == model.n
    }
}

impl Spare for LaneWorkspace {
    const POOL: &'static std::thread::LocalKey<RefCell<Vec<Box<Self>>>> = &SPARE_LANES;
    fn new(model: &Model) -> Self {
        LaneWorkspace::new(model)
    }
    fn serves(&self, model: &Model) -> bool {
        self.n() == model.n
    }
}

/// Scratch lent from this thread's spares (or made), handed back when dropped.
struct Lent<T: Spare>(Option<Box<T>>);

impl<T: Spare> Lent<T> {
    fn new(model: &Model) -> Lent<T> {
        let found = T::POOL.with(|s| {
            let mut s = s.borrow_mut();
            let i = s.iter().position(|w| w.serves(model))?;
            Some(s.swap_remove(i))
        });
        Lent(Some(found.unwrap_or_else(|| Box::new(T::new(model)))))
    }

    fn get(&mut self) -> &mut T {
        self.0
            .as_mut()
            .expect("a lent workspace is present until dropped")
    }
}

impl<T: Spare> Drop for Lent<T> {
    fn drop(&mut self) {
        if let Some(ws) = self.0.take() {
            // During thread teardown the spares may be gone already; the scratch is then freed.
            let _ = T::POOL.try_with(|s| {
                let mut s = s.borrow_mut();
                if s.len() < SPARE_MAX {
                    s.push(ws);
                }
            });
        }
    }
}

/// Advances every state by `steps` steps with the same `inputs`, in parallel over the current
/// rayon pool. Stops at the first error (a diverged state) and returns it.
pub fn step_all(
    model: &Model,
    st: &Stepper,
    states: &mut [State],
    inputs: &Inputs,
    steps: usize,
) -> Result<()> {
    states
        .par_chunks_mut(LANES)
        .with_min_len(2)
        .try_for_each_init(
            || {
                (
                    Lent::<Workspace>::new(model),
                    Lent::<LaneWorkspace>::new(model),
                )
            },
            |(ws, lw), group| {
                let outcomes = step_group(model, st, group, inputs, steps, lw.get(), ws.get());
                match outcomes.into_iter().flatten().next() {
                    Some(e) => Err(e),
                    None => Ok(()),
                }
            },
        )
}

/// Calls `f(workspace, item)` on every item of a parallel iterator (states zipped with whatever
/// each one carries: a particle's object, its weight) over the current rayon pool, with one
/// workspace of `model` per rayon split (kept on the thread for the next call), and sums what `f` returns (a count of failures, say).
/// The items' order of processing varies with the thread count; give each item its own random
/// stream and the result does not.
pub fn sum_with_workspace<I, F>(model: &Model, items: I, f: F) -> usize
where
    I: IndexedParallelIterator,
    F: Fn(&mut Workspace, I::Item) -> usize + Sync + Send,
{
    items
        .with_min_len(8)
        .map_init(
            || Lent::<Workspace>::new(model),
            |ws, item| f(ws.get(), item),
        )
        .sum()
}

/// A workspace and lane scratch of one model, lent from this thread's spares (or made) and
/// handed back when dropped: for stepping lane groups ([`step_group`]) inside a parallel
/// iterator's `map_init`.
pub struct Scratch(Lent<Workspace>, Lent<LaneWorkspace>);

impl Scratch {
    /// Scratch for `model`.
    pub fn new(model: &Model) -> Scratch {
        Scratch(
            Lent::<Workspace>::new(model),
            Lent::<LaneWorkspace>::new(model),
        )
    }

    /// The workspace and the lane scratch.
    pub fn get(&mut self) -> (&mut Workspace, &mut LaneWorkspace) {
        (self.0.get(), self.1.get())
    }
}
