//! Many whisker states stepped against one shared model, in parallel.
//!
//! Every state owns its random stream, so the result is bit-for-bit the same whatever the number
//! of threads: work is split between threads, never the random numbers.

use crate::chain::Model;
use crate::dynamics::{step, Inputs, State, Stepper, Workspace};
use crate::error::Result;
use rayon::prelude::*;

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
        || Workspace::new(model),
        |ws, state| {
            for _ in 0..steps {
                step(model, st, state, inputs, ws)?;
            }
            Ok(())
        },
    )
}

/// Calls `f(workspace, item)` on every item of a parallel iterator (states zipped with whatever
/// each one carries: a particle's object, its weight) over the current rayon pool, with one
/// workspace of `model` per rayon split, and sums what `f` returns (a count of failures, say).
/// The items' order of processing varies with the thread count; give each item its own random
/// stream and the result does not.
pub fn sum_with_workspace<I, F>(model: &Model, items: I, f: F) -> usize
where
    I: IndexedParallelIterator,
    F: Fn(&mut Workspace, I::Item) -> usize + Sync + Send,
{
    items
        .with_min_len(8)
        .map_init(|| Workspace::new(model), |ws, item| f(ws, item))
        .sum()
}
