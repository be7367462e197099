//! NumPy arrays in and out: each argument read, whatever its layout, into the shape and C-order
//! data the set's validation takes ([`Named`]), or refused naming the argument; results handed
//! to NumPy without a copy.

use numpy::ndarray::{ArrayD, IxDyn};
use numpy::{PyArrayDyn, PyArrayMethods, PyUntypedArray, PyUntypedArrayMethods};
use pyo3::prelude::*;
use rrskin_tools::import::numpy_folder::Named;
use std::path::PathBuf;

/// `what`'s dtype in words, for an error.
fn dtype_of(what: &Bound<'_, PyAny>) -> String {
    match what.cast::<PyUntypedArray>() {
        Ok(array) => format!("dtype {}", array.dtype()),
        Err(_) => format!("a {}, not a NumPy array", type_name(what)),
    }
}

fn type_name(what: &Bound<'_, PyAny>) -> String {
    what.get_type()
        .name()
        .map_or_else(|_| "value".to_string(), |n| n.to_string())
}

/// `array` read in C order, whatever its strides.
fn read<T: numpy::Element + Copy + Into<U>, U>(
    array: &Bound<'_, PyArrayDyn<T>>,
    name: &str,
) -> Named<U> {
    let view = array.readonly();
    let view = view.as_array();
    Named {
        name: PathBuf::from(name),
        shape: view.shape().iter().map(|&n| n as u64).collect(),
        data: view.iter().map(|&x| x.into()).collect(),
    }
}

/// Argument `name`: an array of dtype `Wide` or `Narrow` (`kinds` in words), read as `Wide`.
fn either<Wide, Narrow>(what: &Bound<'_, PyAny>, name: &str, kinds: &str) -> PyResult<Named<Wide>>
where
    Wide: numpy::Element + Copy,
    Narrow: numpy::Element + Copy + Into<Wide>,
{
    if let Ok(a) = what.cast::<PyArrayDyn<Wide>>() {
        return Ok(read(a, name));
    }
    if let Ok(a) = what.cast::<PyArrayDyn<Narrow>>() {
        return Ok(read(a, name));
    }
    let found = dtype_of(what);
    Err(crate::error(format!(
        "{name}: {found}, expected {kinds} NumPy array"
    )))
}

/// Argument `name`: a float32 or float64 array.
pub fn floats(what: &Bound<'_, PyAny>, name: &str) -> PyResult<Named<f64>> {
    either::<f64, f32>(what, name, "a float32 or float64")
}

/// Argument `name`: an int32 or int64 array.
pub fn ints(what: &Bound<'_, PyAny>, name: &str) -> PyResult<Named<i64>> {
    either::<i64, i32>(what, name, "an int32 or int64")
}

/// Argument `name`: a sequence of strings.
pub fn strings(what: &Bound<'_, PyAny>, name: &str) -> PyResult<Named<String>> {
    let data: Vec<String> = what.extract().map_err(|_| {
        let found = type_name(what);
        crate::error(format!("{name}: a {found}, expected a list of strings"))
    })?;
    Ok(Named {
        name: PathBuf::from(name),
        shape: vec![data.len() as u64],
        data,
    })
}

/// A new NumPy array of `shape` owning `data` (C order).
pub fn owned<'py, T: numpy::Element>(
    py: Python<'py>,
    shape: &[usize],
    data: Vec<T>,
) -> PyResult<Bound<'py, PyArrayDyn<T>>> {
    let array = ArrayD::from_shape_vec(IxDyn(shape), data).map_err(crate::error)?;
    Ok(numpy::PyArray::from_owned_array(py, array))
}
