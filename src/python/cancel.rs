//! `CancelToken`: the core's [`CancelToken`], put in force by a `with` block in the thread
//! that makes the calls.

use crate::bus::{CancelToken, Entered};
use pyo3::prelude::*;
use pyo3::types::PyTuple;
use std::cell::RefCell;

thread_local! {
    /// The tokens of the `with` blocks this thread is in, innermost last.
    static ENTERED: RefCell<Vec<Entered>> = const { RefCell::new(Vec::new()) };
}

/// Cancels the calls made inside its `with` block, from any thread: `token.cancel()`.
#[pyclass(frozen, module = "benchbus._core", name = "CancelToken")]
pub(super) struct PyCancelToken {
    token: CancelToken,
}

#[pymethods]
impl PyCancelToken {
    #[new]
    fn new() -> Self {
        PyCancelToken {
            token: CancelToken::new(),
        }
    }

    /// Cancels the calls made under this token, now and later; any thread may call it.
    fn cancel(&self) {
        self.token.cancel();
    }

    /// Whether cancel() was called.
    #[getter]
    fn cancelled(&self) -> bool {
        self.token.is_cancelled()
    }

    /// Whether a call made under this token has taken its place in a Bus's queue for the
    /// line (its first turn asked for; a write waiting for the earlier writes to its unit,
    /// its place among them).
    #[getter]
    fn queued(&self) -> bool {
        self.token.has_queued()
    }

    fn __enter__(slf: Bound<'_, Self>) -> Bound<'_, Self> {
        let entered = slf.get().token.enter();
        ENTERED.with(|blocks| blocks.borrow_mut().push(entered));
        slf
    }

    #[pyo3(signature = (*_args))]
    fn __exit__(&self, _args: &Bound<'_, PyTuple>) -> bool {
        ENTERED.with(|blocks| {
            let mut blocks = blocks.borrow_mut();
            if let Some(at) = blocks.iter().rposition(|e| *e.token() == self.token) {
                drop(blocks.remove(at));
            }
        });
        false
    }

    fn __repr__(&self) -> String {
        let cancelled = if self.token.is_cancelled() {
            "True"
        } else {
            "False"
        };
        format!("CancelToken(cancelled={cancelled})")
    }
}
