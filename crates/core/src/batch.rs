//! Many whisker states stepped against one shared model, in parallel.
//!
//! Every state owns its random stream, so the result is bit-for-bit the same whatever the number
//! of threads: work is split between threads, never the random numbers.

use crate::chain::Model;
use crate::dynamics::{step, Inputs, State, Stepper, Workspace};
use crate::error::Result;
use rayon::prelude::*;
use std::cell::RefCell;

thread_local! {
    /// Workspaces kept between parallel calls on this thread (a call makes one per rayon split,
    /// which for a particle filter is thousands of allocations per second otherwise).
    static SPARE: RefCell<Vec<Workspace>> = const { RefCell::new(Vec::new()) };
}

/// Most workspaces a thread keeps.
const SPARE_MAX: usize = 4;

/// A workspace lent from this thread's spares (or made), handed back when dropped.
struct Lent(Option<Workspace>);

impl Lent {
    fn new(model: &Model) -> Lent {
        let found = SPARE.with(|s| {
            let mut s = s.borrow_mut();
            let i = s.iter().position(|w| w.n == model.n)?;
            Some(s.swap_remove(i))
        });
        Lent(Some(found.unwrap_or_else(|| Workspace::new(model))))
    }

    fn get(&mut self) -> &mut Workspace {
        self.0
            .as_mut()
            .expect("a lent workspace is present until dropped")
    }
}

impl Drop for Lent {
    fn drop(&mut self) {
        if let Some(ws) = self.0.take() {
            // During thread teardown the spares may be gone already; the workspace is then freed.
            let _ = SPARE.try_with(|s| {
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
    states.par_iter_mut().with_min_len(8).try_for_each_init(
        || Lent::new(model),
        |ws, state| {
            for _ in 0..steps {
                step(model, st, state, inputs, ws.get())?;
            }
            Ok(())
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
        .map_init(|| Lent::new(model), |ws, item| f(ws.get(), item))
        .sum()
}
