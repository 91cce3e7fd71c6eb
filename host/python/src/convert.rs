//! Python values to Rust and back: numbers from lists, tuples and numpy arrays of any real
//! dtype, checked for type and shape (a clear `InvalidArgument` otherwise; the values
//! themselves, NaN and ranges, are checked by the Rust API); results as numpy arrays that own
//! the Rust buffers they came from (no copy).

use numpy::{
    PyArray, PyArray1, PyArrayDescrMethods, PyReadonlyArrayDyn, PyUntypedArray,
    PyUntypedArrayMethods,
};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyBytes, PyFloat, PyInt, PyString};

use crate::errors::invalid;

/// Nested sequences deeper than this are refused (a shape of at most three axes is asked for
/// anywhere).
const MAX_DEPTH: usize = 3;
/// Sequences longer than this are refused: more values than any call takes (a point cloud's
/// rows, a trajectory's samples).
const MAX_VALUES: usize = 1 << 26;

/// Numbers with their shape (row-major).
pub struct Numbers {
    /// Length along each axis.
    pub shape: Vec<usize>,
    /// The values, row-major.
    pub data: Vec<f64>,
}

fn describe(obj: &Bound<'_, PyAny>) -> String {
    if obj.is_none() {
        return "None".into();
    }
    let ty = obj
        .get_type()
        .name()
        .map(|n| n.to_string())
        .unwrap_or_else(|_| "?".into());
    if let Ok(a) = obj.cast::<PyUntypedArray>() {
        let dt = a.dtype().str().map(|s| s.to_string()).unwrap_or_default();
        return format!("an array of dtype {dt} and shape {:?}", a.shape());
    }
    match obj.len() {
        Ok(n) => format!("a {ty} of length {n}"),
        Err(_) => format!("a {ty}"),
    }
}

/// Reads real numbers of any shape (a scalar, a sequence, nested sequences, a numpy array of
/// a boolean, integer or floating dtype). `what` names the argument in errors.
pub fn numbers(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Numbers> {
    let py = obj.py();
    let bad = || invalid(py, what, "real numbers", describe(obj));
    if let Ok(a) = obj.cast::<PyUntypedArray>() {
        let kind = a.dtype().kind();
        if !matches!(kind, b'b' | b'i' | b'u' | b'f') {
            return Err(bad());
        }
        let as_f64 = obj.call_method1("astype", ("float64",))?;
        let arr: PyReadonlyArrayDyn<'_, f64> = as_f64.extract().map_err(|_| bad())?;
        let view = arr.as_array();
        return Ok(Numbers {
            shape: view.shape().to_vec(),
            data: view.iter().copied().collect(),
        });
    }
    let mut out = Numbers {
        shape: Vec::new(),
        data: Vec::new(),
    };
    nested(obj, what, 0, &mut out.shape, &mut out.data)?;
    Ok(out)
}

fn scalar(obj: &Bound<'_, PyAny>) -> Option<f64> {
    if obj.is_instance_of::<PyBool>() {
        return None;
    }
    if obj.is_instance_of::<PyFloat>() || obj.is_instance_of::<PyInt>() {
        return obj.extract::<f64>().ok();
    }
    // numpy's scalars (np.float32(1), np.int64(2)) have a zero-dimensional dtype; strings and
    // bytes have __float__ nowhere, but are refused by name to say so plainly.
    if obj.is_instance_of::<PyString>() || obj.is_instance_of::<PyBytes>() {
        return None;
    }
    if obj.hasattr("dtype").unwrap_or(false) && obj.hasattr("__float__").unwrap_or(false) {
        return obj.extract::<f64>().ok();
    }
    None
}

fn nested(
    obj: &Bound<'_, PyAny>,
    what: &str,
    depth: usize,
    shape: &mut Vec<usize>,
    data: &mut Vec<f64>,
) -> PyResult<()> {
    let py = obj.py();
    let bad = || invalid(py, what, "real numbers", describe(obj));
    if let Some(v) = scalar(obj) {
        data.push(v);
        return Ok(());
    }
    if depth >= MAX_DEPTH
        || obj.is_none()
        || obj.is_instance_of::<PyString>()
        || obj.is_instance_of::<PyBytes>()
        || obj.is_instance_of::<PyBool>()
        || obj.is_instance_of::<pyo3::types::PyDict>()
    {
        return Err(bad());
    }
    if let Ok(a) = obj.cast::<PyUntypedArray>() {
        // An array inside a list: its own shape continues the outer one.
        let inner = numbers(a.as_any(), what)?;
        return merge(py, what, depth, shape, data, inner);
    }
    let Ok(n) = obj.len() else {
        return Err(bad());
    };
    if data.len() + n > MAX_VALUES {
        return Err(invalid(
            py,
            what,
            &format!("at most {MAX_VALUES} values"),
            describe(obj),
        ));
    }
    let items = obj.try_iter().map_err(|_| bad())?;
    let mut first: Option<Vec<usize>> = None;
    for item in items {
        let item = item?;
        let mut sub = Vec::new();
        nested(&item, what, depth + 1, &mut sub, data)?;
        match &first {
            None => first = Some(sub),
            Some(f) if *f == sub => {}
            Some(_) => {
                return Err(invalid(
                    py,
                    what,
                    "rows of equal length",
                    "a ragged sequence".into(),
                ))
            }
        }
    }
    shape.push(n);
    shape.extend(first.unwrap_or_default());
    Ok(())
}

fn merge(
    py: Python<'_>,
    what: &str,
    depth: usize,
    shape: &mut Vec<usize>,
    data: &mut Vec<f64>,
    inner: Numbers,
) -> PyResult<()> {
    if depth + inner.shape.len() > MAX_DEPTH || data.len() + inner.data.len() > MAX_VALUES {
        return Err(invalid(
            py,
            what,
            "at most three axes",
            format!("an array of shape {:?}", inner.shape),
        ));
    }
    shape.extend(inner.shape);
    data.extend(inner.data);
    Ok(())
}

/// A vector of numbers: any shape with at most one axis longer than 1 (a list, a row, a
/// column), of any length when `len` is `None`.
pub fn vector(obj: &Bound<'_, PyAny>, what: &str, len: Option<usize>) -> PyResult<Vec<f64>> {
    let n = numbers(obj, what)?;
    let long = n.shape.iter().filter(|&&d| d != 1).count();
    let expected = match len {
        Some(l) => format!("{l} numbers"),
        None => "a vector of numbers".into(),
    };
    if n.shape.is_empty() || long > 1 || len.is_some_and(|l| l != n.data.len()) {
        return Err(invalid(obj.py(), what, &expected, describe(obj)));
    }
    Ok(n.data)
}

/// Exactly `N` numbers.
pub fn array<const N: usize>(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<[f64; N]> {
    let v = vector(obj, what, Some(N))?;
    let mut a = [0.0; N];
    a.copy_from_slice(&v);
    Ok(a)
}

/// Rows of `N` numbers: shape `(k, N)`.
pub fn rows<const N: usize>(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec<[f64; N]>> {
    let n = numbers(obj, what)?;
    if n.shape.len() != 2 || n.shape[1] != N {
        return Err(invalid(
            obj.py(),
            what,
            &format!("an array of shape (k, {N})"),
            describe(obj),
        ));
    }
    Ok(n.data
        .chunks_exact(N)
        .map(|c| {
            let mut a = [0.0; N];
            a.copy_from_slice(c);
            a
        })
        .collect())
}

/// Integers (pixel rows or columns), from a list or an integer array.
pub fn integers(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec<i64>> {
    let n = numbers(obj, what)?;
    let bad = || invalid(obj.py(), what, "integers", describe(obj));
    if n.shape.len() > 1 {
        return Err(bad());
    }
    n.data
        .iter()
        .map(|&v| {
            if v.fract() == 0.0 && v.abs() < 9.0e15 {
                Ok(v as i64)
            } else {
                Err(bad())
            }
        })
        .collect()
}

/// An `f64` vector as a 1-D numpy array (the Vec's buffer, moved).
pub fn vec1(py: Python<'_>, v: Vec<f64>) -> Bound<'_, PyAny> {
    PyArray1::from_vec(py, v).into_any()
}

/// A row-major buffer as a numpy array of `shape` (the buffer moved, reshaped in place).
pub fn shaped<'py, T: numpy::Element>(
    py: Python<'py>,
    data: Vec<T>,
    shape: &[usize],
) -> PyResult<Bound<'py, PyAny>> {
    let array = numpy::ndarray::ArrayD::from_shape_vec(shape, data).map_err(|e| {
        pyo3::exceptions::PyValueError::new_err(format!("array of shape {shape:?}: {e}"))
    })?;
    Ok(PyArray::from_owned_array(py, array).into_any())
}

/// A 3x3 matrix (rows) as a numpy array.
pub fn mat3(py: Python<'_>, m: [[f64; 3]; 3]) -> PyResult<Bound<'_, PyAny>> {
    shaped(py, m.concat(), &[3, 3])
}

/// A position as PyRobot returns it: a 3x1 column.
pub fn column3(py: Python<'_>, p: [f64; 3]) -> PyResult<Bound<'_, PyAny>> {
    shaped(py, p.to_vec(), &[3, 1])
}

/// A flag as Python reads one: any object by its truth value (`if plan:`), as PyRobot read its
/// keyword arguments (numpy's booleans, 0 and 1 included; PyRobot's tests pass `"False"`).
pub fn truthy(obj: &Bound<'_, PyAny>) -> PyResult<bool> {
    obj.is_truthy()
}
