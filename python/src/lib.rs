//! rrskin for Python (`import rrskin`): the module `rrskin._rrskin`, which the package
//! `rrskin` (python/rrskin) re-exports, typed by `python/rrskin/_rrskin.pyi`.
//!
//! The contract:
//! - **Arrays in** are NumPy arrays: float32 or float64 for coordinates and transforms, int32
//!   or int64 for indices, in any memory layout (a non-contiguous array is read through its
//!   strides). A set is validated as the NumPy folder loader validates its files
//!   ([`rrskin_tools::set::ExampleSet::from_arrays`]), each error naming the argument and the
//!   index at fault.
//! - **Arrays out** are new NumPy arrays that own what Rust computed (no copy on the way out):
//!   float32 for what the runtime computes (deformed vertices, palettes, the skin), float64 for
//!   an example set's data.
//! - **Errors** are `rrskin.Error` (bad input, a failed training, an unreadable file), with
//!   the message the CLI prints; nothing panics into Python. A progress callback's exception,
//!   or Ctrl-C (KeyboardInterrupt), stops training at its next stage and is raised as it was.
//! - **Threads**: training, evaluation and deformation release the GIL (`Python::detach`);
//!   training runs its stages on the rayon pool as the CLI does.

mod arrays;
mod model;
mod set;
mod train;

use pyo3::prelude::*;

pyo3::create_exception!(
    rrskin,
    Error,
    pyo3::exceptions::PyException,
    "Bad input, a failed training or an unreadable file: the message names the argument or \
     file, and what is wrong."
);

/// `rrskin.Error` with `error`'s message.
fn error(error: impl std::fmt::Display) -> PyErr {
    Error::new_err(error.to_string())
}

/// A JSON value as the Python object `json.loads` makes of it (dicts, lists, numbers, None).
fn to_python<'py>(py: Python<'py>, value: &serde_json::Value) -> PyResult<Bound<'py, PyAny>> {
    let json = py.import("json")?;
    json.call_method1("loads", (value.to_string(),))
}

#[pymodule]
fn _rrskin(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("Error", m.py().get_type::<Error>())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_class::<set::ExampleSet>()?;
    m.add_class::<model::Model>()?;
    m.add_function(wrap_pyfunction!(set::load_set, m)?)?;
    m.add_function(wrap_pyfunction!(train::train, m)?)?;
    m.add_function(wrap_pyfunction!(train::evaluate, m)?)?;
    Ok(())
}
