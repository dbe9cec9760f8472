//! NumPy in and out: reading the arguments of the batch calls (one vector
//! of shape `(K,)` or `N` of them, shape `(N, K)`, as float32 or float64),
//! and the parallel loop that runs a batch in chunks.

use numpy::ndarray::{ArrayView1, Axis};
use numpy::{
    Element, PyArrayDescrMethods, PyArrayDyn, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArray,
    PyUntypedArrayMethods,
};
use pyo3::prelude::*;
use rayon::prelude::*;

use crate::errors::raise;

/// Batches of at least this many rows run on rayon's pool; smaller ones on
/// the calling thread (a single Mitsuba `scalar_rgb` call is one row).
pub const PARALLEL_MIN: usize = 8192;

/// Rows per task of a parallel batch.
const CHUNK: usize = 2048;

/// One argument of a batch call: a single `K`-vector, broadcast against the
/// other arguments, or one per row.
#[derive(Debug, Clone)]
pub enum Rows<const K: usize> {
    One([f32; K]),
    Many(Vec<[f32; K]>),
}

impl<const K: usize> Rows<K> {
    /// The row count, `None` for a single vector.
    pub fn len(&self) -> Option<usize> {
        match self {
            Rows::One(_) => None,
            Rows::Many(v) => Some(v.len()),
        }
    }

    /// Row `k` (the single vector for every `k`).
    #[inline]
    pub fn get(&self, k: usize) -> [f32; K] {
        match self {
            Rows::One(v) => *v,
            Rows::Many(v) => v[k],
        }
    }

    /// Apply `f` to every vector.
    pub fn map_in_place(&mut self, f: impl Fn([f32; K]) -> [f32; K]) {
        match self {
            Rows::One(v) => *v = f(*v),
            Rows::Many(v) => v.iter_mut().for_each(|r| *r = f(*r)),
        }
    }
}

/// Read argument `name` of `K` components: a NumPy array of float32 or
/// float64, of shape `(K,)` or `(N, K)`; anything else that is not a NumPy
/// array (a list, a tuple, a Dr.Jit array) goes through
/// `numpy.asarray(obj, dtype=float64)` first. A NumPy array of another
/// dtype raises `acdf.DTypeError`, as does what `asarray` cannot convert;
/// another shape raises `acdf.ShapeError`. float64 is rounded to float32,
/// the precision of every computation.
pub fn read<const K: usize>(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<Rows<K>> {
    let py = obj.py();
    let bad_dtype = |what: String| {
        raise(
            py,
            "DTypeError",
            format!("`{name}` must be an array of float32 or float64, {what}"),
        )
    };
    if obj.is_none() {
        return Err(bad_dtype("got None".into()));
    }
    let array = match obj.cast::<PyUntypedArray>() {
        Ok(a) => a.clone(),
        Err(_) => py
            .import("numpy")?
            .call_method1("asarray", (obj, "float64"))
            .map_err(|e| bad_dtype(format!("and {e}")))?
            .cast_into::<PyUntypedArray>()?,
    };
    let dtype = array.dtype();
    if dtype.is_equiv_to(&numpy::dtype::<f32>(py)) {
        rows_of::<f32, K>(&array, name, |x| x)
    } else if dtype.is_equiv_to(&numpy::dtype::<f64>(py)) {
        rows_of::<f64, K>(&array, name, |x| x as f32)
    } else {
        Err(bad_dtype(format!("got dtype {dtype}")))
    }
}

fn rows_of<T: Element + Copy, const K: usize>(
    array: &Bound<'_, PyUntypedArray>,
    name: &str,
    to_f32: impl Fn(T) -> f32,
) -> PyResult<Rows<K>> {
    let py = array.py();
    let typed = array.cast::<PyArrayDyn<T>>()?;
    let readonly: PyReadonlyArrayDyn<'_, T> = typed.readonly();
    let view = readonly.as_array();
    let shape = view.shape();
    let bad_shape = || {
        raise(
            py,
            "ShapeError",
            format!(
                "`{name}` must have shape ({K},) or (N, {K}), got {}",
                shape_text(shape)
            ),
        )
    };
    let vector = |row: ArrayView1<'_, T>| {
        let mut v = [0.0f32; K];
        for (slot, &x) in v.iter_mut().zip(row.iter()) {
            *slot = to_f32(x);
        }
        v
    };
    match shape {
        [k] if *k == K => Ok(Rows::One(vector(
            view.view().into_dimensionality().map_err(|_| bad_shape())?,
        ))),
        [_, k] if *k == K => Ok(Rows::Many(
            view.axis_iter(Axis(0))
                .map(|row| vector(row.into_dimensionality().expect("a row of a 2-D array")))
                .collect(),
        )),
        _ => Err(bad_shape()),
    }
}

/// A shape as NumPy prints it: `(3,)`, `(5, 2)`.
fn shape_text(shape: &[usize]) -> String {
    match shape {
        [n] => format!("({n},)"),
        _ => format!(
            "({})",
            shape
                .iter()
                .map(usize::to_string)
                .collect::<Vec<_>>()
                .join(", ")
        ),
    }
}

/// The common row count of a call's arguments: `None` when every argument
/// is a single vector, else the `N` they share (single vectors broadcast).
/// Differing counts raise `acdf.ShapeError`.
pub fn common_len(py: Python<'_>, lens: &[(&str, Option<usize>)]) -> PyResult<Option<usize>> {
    let mut found: Option<(&str, usize)> = None;
    for &(name, len) in lens {
        match (found, len) {
            (_, None) => {}
            (None, Some(n)) => found = Some((name, n)),
            (Some((first, m)), Some(n)) if m != n => {
                return Err(raise(
                    py,
                    "ShapeError",
                    format!("`{first}` has {m} rows but `{name}` has {n}"),
                ))
            }
            (Some(_), Some(_)) => {}
        }
    }
    Ok(found.map(|(_, n)| n))
}

/// Unit length as the computations expect it: a vector whose squared length
/// differs from 1 by more than float32 rounding is normalised (a zero or
/// non-finite one becomes 0, which every call treats as below the horizon);
/// a unit vector is used as given, bit for bit.
pub fn unit(v: [f32; 3]) -> [f32; 3] {
    let g = glam::Vec3::from(v);
    if (g.length_squared() - 1.0).abs() <= 4.0 * f32::EPSILON {
        v
    } else {
        g.normalize_or_zero().into()
    }
}

/// Run `each(start, out_chunk)` over `out` in chunks: on rayon's pool when
/// `out` has at least [`PARALLEL_MIN`] items, else on this thread.
pub fn chunked<T: Send>(out: &mut [T], each: impl Fn(usize, &mut [T]) + Sync) {
    if out.len() < PARALLEL_MIN {
        each(0, out);
    } else {
        out.par_chunks_mut(CHUNK)
            .enumerate()
            .for_each(|(k, chunk)| each(k * CHUNK, chunk));
    }
}
