//! NumPy in and out: reading the arguments of the batch calls (one vector
//! of shape `(K,)` or `N` of them, shape `(N, K)`, as float32 or float64),
//! and the parallel loop that runs a batch in chunks.

use std::borrow::Cow;

use acdf_core::{Vec2, Vec3};
use numpy::ndarray::Axis;
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
pub const CHUNK: usize = 2048;

/// A row type of the batch calls: a direction ([`Vec3`]) or a pair of
/// uniform numbers ([`Vec2`]).
pub trait Row: Copy + Send + Sync + 'static {
    /// Components per row.
    const K: usize;
    /// The row of `K` components.
    fn from_components(c: &[f32]) -> Self;
}

impl Row for Vec3 {
    const K: usize = 3;
    #[inline]
    fn from_components(c: &[f32]) -> Self {
        Vec3::new(c[0], c[1], c[2])
    }
}

impl Row for Vec2 {
    const K: usize = 2;
    #[inline]
    fn from_components(c: &[f32]) -> Self {
        Vec2::new(c[0], c[1])
    }
}

/// One argument of a batch call: a single row, broadcast against the other
/// arguments, or one per row.
#[derive(Debug, Clone)]
pub enum Rows<T> {
    One(T),
    Many(Vec<T>),
}

impl<T: Row> Rows<T> {
    /// The row count, `None` for a single row.
    pub fn len(&self) -> Option<usize> {
        match self {
            Rows::One(_) => None,
            Rows::Many(v) => Some(v.len()),
        }
    }

    /// Rows `start..start + n`: a view of them, or the single row repeated.
    pub fn chunk(&self, start: usize, n: usize) -> Cow<'_, [T]> {
        match self {
            Rows::One(v) => Cow::Owned(vec![*v; n]),
            Rows::Many(v) => Cow::Borrowed(&v[start..start + n]),
        }
    }

    /// Apply `f` to every row (in parallel for a large batch).
    pub fn map_in_place(&mut self, f: impl Fn(T) -> T + Sync) {
        match self {
            Rows::One(v) => *v = f(*v),
            Rows::Many(v) => chunked(v, |_, c| c.iter_mut().for_each(|r| *r = f(*r))),
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
pub fn read<T: Row>(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<Rows<T>> {
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
        rows_of::<f32, T>(&array, name, |x| x)
    } else if dtype.is_equiv_to(&numpy::dtype::<f64>(py)) {
        rows_of::<f64, T>(&array, name, |x| x as f32)
    } else {
        Err(bad_dtype(format!("got dtype {dtype}")))
    }
}

fn rows_of<E: Element + Copy, T: Row>(
    array: &Bound<'_, PyUntypedArray>,
    name: &str,
    to_f32: impl Fn(E) -> f32,
) -> PyResult<Rows<T>> {
    let py = array.py();
    let typed = array.cast::<PyArrayDyn<E>>()?;
    let readonly: PyReadonlyArrayDyn<'_, E> = typed.readonly();
    let view = readonly.as_array();
    let k = T::K;
    let row = |values: &mut dyn Iterator<Item = &E>| {
        let mut c = [0.0f32; 3];
        for (slot, &x) in c.iter_mut().zip(values) {
            *slot = to_f32(x);
        }
        T::from_components(&c[..k])
    };
    match view.shape() {
        [n] if *n == k => Ok(Rows::One(row(&mut view.iter()))),
        // In C order (NumPy's `as_slice` would also take a Fortran-ordered
        // buffer, whose rows are not contiguous): read the buffer directly.
        [_, n] if *n == k => Ok(Rows::Many(match view.as_slice() {
            Some(flat) => flat.chunks_exact(k).map(|c| row(&mut c.iter())).collect(),
            None => view
                .axis_iter(Axis(0))
                .map(|r| row(&mut r.iter()))
                .collect(),
        })),
        shape => Err(raise(
            py,
            "ShapeError",
            format!(
                "`{name}` must have shape ({k},) or (N, {k}), got {}",
                shape_text(shape)
            ),
        )),
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

/// The two directions of `eval` and `pdf`, read and checked: (wo, wi, N).
pub fn direction_pair(
    wo: &Bound<'_, PyAny>,
    wi: &Bound<'_, PyAny>,
) -> PyResult<(Rows<Vec3>, Rows<Vec3>, Option<usize>)> {
    let py = wo.py();
    let (wo, wi) = (read::<Vec3>(wo, "wo")?, read::<Vec3>(wi, "wi")?);
    let n = common_len(py, &[("wo", wo.len()), ("wi", wi.len())])?;
    Ok((wo, wi, n))
}

impl Rows<Vec3> {
    /// Every direction of unit length ([`unit`]).
    pub fn normalised(mut self) -> Self {
        self.map_in_place(unit);
        self
    }
}

/// Unit length as the computations expect it: a vector whose squared length
/// differs from 1 by more than float32 rounding is normalised (a zero or
/// non-finite one becomes 0, which every call treats as below the horizon);
/// a unit vector is used as given, bit for bit.
pub fn unit(v: Vec3) -> Vec3 {
    if (v.length_squared() - 1.0).abs() <= 4.0 * f32::EPSILON {
        v
    } else {
        v.normalize_or_zero()
    }
}

/// Run `each(start_row, out_chunk)` over `out` in chunks: on rayon's pool
/// when `out` has at least [`PARALLEL_MIN`] items, else on this thread.
pub fn chunked<T: Send>(out: &mut [T], each: impl Fn(usize, &mut [T]) + Sync) {
    chunked_by(out, 1, each)
}

/// [`chunked`] for `out` holding `width` values per row: the chunks hold
/// whole rows and `start_row` counts rows.
pub fn chunked_by<T: Send>(out: &mut [T], width: usize, each: impl Fn(usize, &mut [T]) + Sync) {
    if out.len() < PARALLEL_MIN * width {
        each(0, out);
    } else {
        out.par_chunks_mut(CHUNK * width)
            .enumerate()
            .for_each(|(k, chunk)| each(k * CHUNK, chunk));
    }
}
