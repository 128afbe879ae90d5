//! `normalfit._normalfit`: the library's calls for Python, on NumPy arrays.
//!
//! Everything here only translates: Python values into the library's
//! options and slices, the library's results and errors back. No rule of
//! the conversion is made here (the fit, its encodings, the tiling check
//! and their messages are the library's). The public functions, with their
//! keyword defaults and docstrings, are in `python/normalfit/__init__.py`,
//! which calls these with every argument given.
//!
//! What holds at this boundary:
//! * Nothing a caller passes panics: wrong types and shapes are `TypeError`
//!   or `ValueError`, the library's errors are mapped by [`to_py_err`], and
//!   output arrays are made by `numpy.empty`, which raises `MemoryError`
//!   where a direct allocation would abort.
//! * The GIL is released while the library works (`Python::detach`), so
//!   other Python threads run, including other conversions.
//! * A C-contiguous, aligned array of a native dtype is read in place; any
//!   other layout is copied once, in row order, with the GIL released.
#![deny(unsafe_code)]

use std::collections::HashMap;
use std::sync::Mutex;

use std::path::{Path, PathBuf};

use normalfit::blend::{BlendOptions, Method as BlendMethod};
use normalfit::check::{CheckOptions, CheckReport, FixOptions, MapLayout, check_and_fix};
use normalfit::convert::{BorderChoice, BorderChoices, Conversion, Place};
use normalfit::fit::{Halo, HaloPlan, Window};
use normalfit::height::file::HeightConversion;
use normalfit::height::{ConventionChoice, HeightOptions, Model, heights_of_rows_with_holes};
use normalfit::inspect;
use normalfit::io::{
    Affine, ByteOrder, Channel, Layout, OutputFormat, PackedElevation, PngCompression, RawOptions, ReadOptions,
};
use normalfit::mips::{MipChoice, MipLevel};
use normalfit::normal_map::ImageKind;
use normalfit::normal_map::{self, Storage};
use normalfit::options::UnitsName;
use normalfit::products::{hillshade_into, measure_into};
use normalfit::shade::Sun;
use normalfit::shade::{self, Light, LitOptions};
use normalfit::tiling::{self, TilingOptions};
use normalfit::units::{Crs, MapSpacing, Measure};
use normalfit::{
    Border, Convention, Detail, Error, Fit, FitRequest, FromNormal, Options, Product, Sample, Samples, SlopeUnits,
    Spacing, Strength, Units, Weights,
};
use numpy::ndarray::ArrayView2;
use numpy::{
    Element, PyArray1, PyArray2, PyArray3, PyArrayDescr, PyArrayDescrMethods, PyArrayMethods, PyReadonlyArray2,
    PyUntypedArray, PyUntypedArrayMethods, dtype,
};
use pyo3::exceptions::{PyMemoryError, PyOSError, PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyInt, PyList, PyString, PyTuple};
use rayon::ThreadPool;

/// The most threads `threads=` may ask for: far more than any machine's
/// cores, few enough that a typo cannot try to start a million threads.
const MAX_THREADS: usize = 1024;

/// The library's error as the Python exception a caller expects: options,
/// sizes and heights are the caller's values (`ValueError`), memory is
/// `MemoryError`, the operating system's failures `OSError`. The message is
/// the library's one line.
fn to_py_err(e: Error) -> PyErr {
    match e {
        Error::Limits(_) => PyMemoryError::new_err(e.to_string()),
        Error::Io(ref io) => PyOSError::new_err((io.raw_os_error().unwrap_or(0), e.to_string())),
        _ => PyValueError::new_err(e.to_string()),
    }
}

/// A name the library parses (`fit`, `convention`, a border), its error a
/// `ValueError` with the library's message.
fn parse_named<T: std::str::FromStr<Err = Error>>(name: &str) -> PyResult<T> {
    name.parse().map_err(to_py_err)
}

/// `border=`: one mode for both axes, `"x,y"` as on the command line, or
/// an `(x, y)` pair; `auto` is wrap where the image tiles, mirror where not.
fn parse_borders(border: &Bound<'_, PyAny>) -> PyResult<BorderChoices> {
    if let Ok(s) = border.cast::<PyString>() {
        let s = s.to_cow()?;
        return parse_named(&s);
    }
    if let Ok(pair) = border.cast::<PyTuple>()
        && pair.len() == 2
    {
        let (x, y): (String, String) = pair.extract()?;
        return Ok(BorderChoices { x: parse_named(&x)?, y: parse_named(&y)? });
    }
    Err(PyTypeError::new_err(format!("border must be a mode name or an (x, y) pair of them, got {}", shown(border))))
}

/// An int argument as i128: a negative or huge value is then an option out
/// of range (`ValueError`, as on the command line), not an `OverflowError`.
fn whole(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<i128> {
    if obj.cast::<PyInt>().is_err() {
        let type_name = obj.get_type().name().map_or_else(|_| "?".into(), |n| n.to_string());
        return Err(PyTypeError::new_err(format!("{name} must be an int, got {type_name}")));
    }
    obj.extract::<i128>()
        .map_err(|_| PyValueError::new_err(format!("invalid option: {name} is out of range, got {}", shown(obj))))
}

/// A count argument (`max_texels`) as u64: a negative or huge int is an
/// option out of range (`ValueError`, as on the command line), not the
/// `OverflowError` of a plain conversion; the library checks the rest.
fn count(obj: Option<&Bound<'_, PyAny>>, name: &str) -> PyResult<Option<u64>> {
    let Some(obj) = obj else { return Ok(None) };
    let n = whole(obj, name)?;
    u64::try_from(n)
        .map(Some)
        .map_err(|_| PyValueError::new_err(format!("invalid option: {name} is out of range, got {n}")))
}

/// `repr(obj)`, for messages.
fn shown(obj: &Bound<'_, PyAny>) -> String {
    obj.repr().map_or_else(|_| "?".into(), |r| r.to_string())
}

/// The fit's options from the keyword arguments, checked by the library,
/// and the border choices (which may be `auto`).
#[allow(clippy::too_many_arguments)]
fn fit_options(
    patch: &Bound<'_, PyAny>,
    fit: &str,
    border: &Bound<'_, PyAny>,
    convention: &str,
    scale: Option<f64>,
    relief: Option<f64>,
    invert: bool,
) -> PyResult<(Options, BorderChoices)> {
    let patch = whole(patch, "patch")?;
    let Ok(patch) = usize::try_from(patch) else {
        return Err(PyValueError::new_err(format!(
            "invalid option: patch size must be odd and at least 3, got {patch}"
        )));
    };
    let strength = Strength::from_scale_or_relief(scale, relief).map_err(to_py_err)?;
    let borders = parse_borders(border)?;
    let opts = Options::new()
        .with_patch(patch)
        .with_fit(parse_named::<Fit>(fit)?)
        .with_convention(parse_named::<Convention>(convention)?)
        .with_strength(strength)
        .with_invert(invert);
    opts.validate().map_err(to_py_err)?;
    Ok((opts, borders))
}

/// `opts` with `weights=` (`"uniform"` or `"binomial"`), which the library
/// parses and checks with the rest of the options.
fn with_weights(opts: Options, weights: &str) -> PyResult<Options> {
    let opts = opts.with_weights(parse_named::<Weights>(weights)?);
    opts.validate().map_err(to_py_err)?;
    Ok(opts)
}

/// `opts` with `detail=` (a sequence of `(N, weight)` pairs, or None),
/// which the library checks with the rest of the options.
fn with_detail(opts: Options, detail: Option<&Bound<'_, PyAny>>) -> PyResult<Options> {
    let Some(detail) = detail.filter(|d| !d.is_none()) else { return Ok(opts) };
    let pairs =
        || PyTypeError::new_err(format!("detail must be a sequence of (N, weight) pairs, got {}", shown(detail)));
    let mut scales = Vec::new();
    for item in detail.try_iter().map_err(|_| pairs())? {
        let (n, weight): (Bound<'_, PyAny>, f64) = item?.extract().map_err(|_| pairs())?;
        let n = whole(&n, "detail patch size")?;
        let n = usize::try_from(n).map_err(|_| {
            PyValueError::new_err(format!("invalid option: detail patch size must be odd and at least 3, got {n}"))
        })?;
        scales.push((n, weight));
    }
    let opts = opts.with_detail(Some(Detail::new(scales).map_err(to_py_err)?));
    opts.validate().map_err(to_py_err)?;
    Ok(opts)
}

/// The rayon pools of `threads=`, kept by size: starting threads costs
/// more than a small image's fit. A call takes a pool out and puts it back
/// when done, so two concurrent calls never share one (a shared pool of
/// one thread would run them one after the other); a pool is made when
/// none of the size is free.
static POOLS: Mutex<Option<HashMap<usize, Vec<ThreadPool>>>> = Mutex::new(None);

/// A pool taken from [`POOLS`], put back on drop.
struct Borrowed {
    threads: usize,
    pool: Option<ThreadPool>,
}

impl Drop for Borrowed {
    fn drop(&mut self) {
        if let Some(pool) = self.pool.take() {
            let mut pools = POOLS.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
            pools.get_or_insert_with(HashMap::new).entry(self.threads).or_default().push(pool);
        }
    }
}

/// A pool of `threads=` threads, or none (rayon's global pool).
fn pool(threads: Option<&Bound<'_, PyAny>>) -> PyResult<Option<Borrowed>> {
    let Some(n) = thread_count(threads)? else { return Ok(None) };
    let kept = {
        let mut pools = POOLS.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        pools.get_or_insert_with(HashMap::new).get_mut(&n).and_then(Vec::pop)
    };
    let pool = match kept {
        Some(pool) => pool,
        None => rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .thread_name(|i| format!("normalfit-{i}"))
            .build()
            .map_err(|e| PyOSError::new_err(format!("cannot start {n} threads: {e}")))?,
    };
    Ok(Some(Borrowed { threads: n, pool: Some(pool) }))
}

/// `threads=` checked: a count from 1 to [`MAX_THREADS`], or `None` for
/// rayon's global pool.
fn thread_count(threads: Option<&Bound<'_, PyAny>>) -> PyResult<Option<usize>> {
    let Some(n) = threads else { return Ok(None) };
    let n = whole(n, "threads")?;
    match usize::try_from(n).ok().filter(|n| (1..=MAX_THREADS).contains(n)) {
        Some(n) => Ok(Some(n)),
        None => Err(PyValueError::new_err(format!("invalid option: threads must be from 1 to {MAX_THREADS}, got {n}"))),
    }
}

/// The sizes of the pools of `threads=` that are kept and free now, one
/// entry a pool, smallest first: the tests' view of [`POOLS`] (a pool made
/// while another of its size was in use shows here as a second entry).
#[pyfunction]
fn _kept_pools() -> Vec<usize> {
    let pools = POOLS.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
    let mut sizes: Vec<usize> =
        pools.iter().flat_map(|m| m.iter()).flat_map(|(&size, kept)| std::iter::repeat_n(size, kept.len())).collect();
    sizes.sort_unstable();
    sizes
}

/// Runs `work` on the pool of `threads=`, or on rayon's global pool.
fn on_pool<R: Send>(pool: Option<&ThreadPool>, work: impl FnOnce() -> R + Send) -> R {
    match pool {
        Some(p) => p.install(work),
        None => work(),
    }
}

/// The sample types a height array may have.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum SampleKind {
    U8,
    U16,
    F32,
    F64,
}

/// The array's sample type, or the `TypeError` naming what it is.
fn sample_kind(array: &Bound<'_, PyUntypedArray>, what: &str) -> PyResult<SampleKind> {
    sample_kind_of(&array.dtype(), what)
}

/// [`sample_kind`] of an array of dtype `dt`.
fn sample_kind_of(dt: &Bound<'_, PyArrayDescr>, what: &str) -> PyResult<SampleKind> {
    let py = dt.py();
    for (kind, candidate) in [
        (SampleKind::U8, dtype::<u8>(py)),
        (SampleKind::U16, dtype::<u16>(py)),
        (SampleKind::F32, dtype::<f32>(py)),
        (SampleKind::F64, dtype::<f64>(py)),
    ] {
        // Equivalence includes the byte order: a big-endian array is
        // refused rather than read wrong.
        if dt.is_equiv_to(&candidate) {
            return Ok(kind);
        }
    }
    Err(PyTypeError::new_err(format!(
        "{what} must be uint8, uint16, float32 or float64 (native byte order), got {}",
        dt.str()?
    )))
}

/// `heights` as a NumPy array of `ndim` dimensions, or the `TypeError`.
fn as_array<'a, 'py>(
    obj: &'a Bound<'py, PyAny>,
    what: &str,
    ndims: &[usize],
) -> PyResult<&'a Bound<'py, PyUntypedArray>> {
    let array = obj.cast::<PyUntypedArray>().map_err(|_| {
        let type_name = obj.get_type().name().map_or_else(|_| "?".into(), |n| n.to_string());
        PyTypeError::new_err(format!("{what} must be a NumPy array, got {type_name}"))
    })?;
    if !ndims.contains(&array.ndim()) {
        let want = ndims.iter().map(|n| format!("{n}-D")).collect::<Vec<_>>().join(" or ");
        return Err(PyTypeError::new_err(format!("{what} must be a {want} array, got {}-D", array.ndim())));
    }
    Ok(array)
}

/// The elements of a view in row order, in a new vector (the copy an array
/// of any other layout needs), or `MemoryError`-bound `Limits`.
fn row_order<H: Copy>(view: &ArrayView2<'_, H>) -> Result<Vec<H>, Error> {
    let mut v = Vec::new();
    v.try_reserve_exact(view.len())
        .map_err(|_| Error::Limits(format!("cannot allocate a copy of {} heights", view.len())))?;
    v.extend(view.iter().copied());
    Ok(v)
}

/// The heights row after row: the array's own memory where it already
/// is (`in_place`), else a copy.
fn in_row_order<'a, H: Copy>(
    in_place: Option<&'a [H]>,
    view: &ArrayView2<'_, H>,
) -> Result<std::borrow::Cow<'a, [H]>, Error> {
    match in_place {
        Some(s) => Ok(std::borrow::Cow::Borrowed(s)),
        None => row_order(view).map(std::borrow::Cow::Owned),
    }
}

/// A `numpy.empty` array: numpy raises `MemoryError` or `ValueError` for a
/// size it cannot make, where a direct allocation would abort.
fn empty<'py>(py: Python<'py>, shape: &[usize], dt: Bound<'py, PyArrayDescr>) -> PyResult<Bound<'py, PyAny>> {
    let shape = PyTuple::new(py, shape)?;
    py.import("numpy")?.getattr("empty")?.call1((shape, dt))
}

/// The output array: the caller's `out` after checking it, or a new one.
fn output<'py, E: Element>(
    py: Python<'py>,
    out: Option<&Bound<'py, PyAny>>,
    h: usize,
    w: usize,
) -> PyResult<Bound<'py, PyArray3<E>>> {
    let want = dtype::<E>(py);
    let Some(out) = out else {
        return Ok(empty(py, &[h, w, 3], want)?.cast_into::<PyArray3<E>>()?);
    };
    let array = as_array(out, "out", &[3])?;
    if !array.dtype().is_equiv_to(&want) {
        return Err(PyTypeError::new_err(format!(
            "out must have dtype {} (the dtype asked for), got {}",
            want.str()?,
            array.dtype().str()?
        )));
    }
    if array.shape() != [h, w, 3] {
        return Err(PyValueError::new_err(format!("out must have shape ({h}, {w}, 3), got {:?}", array.shape())));
    }
    if !array.is_c_contiguous() {
        return Err(PyValueError::new_err("out must be C-contiguous (written in place, row by row)"));
    }
    Ok(array.cast::<PyArray3<E>>()?.clone())
}

/// What one `normals` call asks for besides the heights.
struct Call<'a, 'py> {
    opts: &'a Options,
    borders: BorderChoices,
    out: Option<&'a Bound<'py, PyAny>>,
    residual: bool,
    pool: Option<Borrowed>,
    /// The heights are this window of a larger image and its halo (and the
    /// output the window's); `None`: the heights are the whole image.
    window: Option<Window>,
}

/// `normals` for heights of sample type `H` into texels of `[E; 3]`.
fn fit_typed<'py, H, E>(heights: &Bound<'py, PyUntypedArray>, call: &Call<'_, 'py>) -> PyResult<Bound<'py, PyAny>>
where
    H: Stored,
    E: Element + Copy + Send,
    [E; 3]: FromNormal,
{
    let py = heights.py();
    let (h, w) = (heights.shape()[0], heights.shape()[1]);
    // The texels computed: the window's, or the whole image's.
    let (ow, oh) = call.window.map_or((w, h), |win| win.size);
    let source = heights.cast::<PyArray2<H>>()?.try_readonly().map_err(borrow_error)?;
    let out = output::<E>(py, call.out, oh, ow)?;
    let residual =
        if call.residual { Some(empty(py, &[oh, ow], dtype::<f32>(py))?.cast_into::<PyArray2<f32>>()?) } else { None };
    // Read in place when the memory is already the rows, one after another.
    let in_place = if heights.is_c_contiguous() { source.as_slice().ok() } else { None };
    let view = source.as_array();
    let mut out_rw = out.try_readwrite().map_err(borrow_error)?;
    let out_flat = out_rw.as_slice_mut().map_err(|e| PyValueError::new_err(format!("out: {e}")))?;
    let (texels, rest) = out_flat.as_chunks_mut::<3>();
    debug_assert!(rest.is_empty());
    let mut residual_rw = match &residual {
        Some(r) => Some(r.try_readwrite().map_err(borrow_error)?),
        None => None,
    };
    let residual_flat = match residual_rw.as_mut() {
        Some(r) => Some(r.as_slice_mut().map_err(|e| PyValueError::new_err(format!("residual: {e}")))?),
        None => None,
    };
    let (choices, pool, window) = (call.borders, call.pool.as_ref().and_then(|b| b.pool.as_ref()), call.window);
    let opts = call.opts;
    py.detach(|| -> Result<(), Error> {
        let heights = in_row_order(in_place, &view)?;
        let heights: &[H] = &heights;
        // A window's borders are fixed modes; the whole image's `auto` is
        // settled by the library's tiling check, as a conversion does.
        let borders = match window {
            Some(_) => window_borders(choices)?,
            None => choices.settle_with_holes(heights, w, h, opts.nodata)?,
        };
        // Missing texels (with nodata, whose output is float32) are NaN.
        let mut request = FitRequest::new(opts).borders(borders).missing([f64::NAN; 3]);
        if let Some(window) = window {
            request = request.window(window);
        }
        if let Some(r) = residual_flat {
            request = request.residual(r);
        }
        on_pool(pool, || request.normals_into(heights, w, h, texels)).map(|_missing| ())
    })
    .map_err(to_py_err)?;
    drop(out_rw);
    drop(residual_rw);
    let out = out.into_any();
    match residual {
        Some(r) => Ok(PyTuple::new(py, [out, r.into_any()])?.into_any()),
        None => Ok(out),
    }
}

/// The sample types an array of heights may hold.
trait Stored: Sample + Element {}

impl<T: Sample + Element> Stored for T {}

/// numpy's borrow checker refused: `out` is read-only (a view numpy marks
/// so, or an array made with `setflags(write=False)`), or the arrays
/// overlap (`out` is a view of `heights`) or another thread holds one
/// mutably.
fn borrow_error(e: numpy::BorrowError) -> PyErr {
    match e {
        numpy::BorrowError::NotWriteable => {
            PyValueError::new_err("out= is read-only: give a writeable array, or none for a new one")
        }
        _ => PyValueError::new_err(format!("out must not share memory with heights ({e})")),
    }
}

/// A chain's levels as arrays of `dtype`: the float normals, or their
/// 8- or 16-bit RGB as the image writers round them.
fn levels_as_arrays<'py>(
    py: Python<'py>,
    chain: Vec<MipLevel<[f32; 3]>>,
    output: OutputKind,
) -> PyResult<Bound<'py, PyList>> {
    fn rounded<T: Element>(py: Python<'_>, level: &MipLevel<[f32; 3]>) -> PyResult<Py<PyAny>>
    where
        [T; 3]: FromNormal,
    {
        let flat: Vec<T> = level.texels.iter().flat_map(|t| <[T; 3]>::from_normal(t.map(f64::from))).collect();
        Ok(PyArray1::from_vec(py, flat).reshape([level.height, level.width, 3])?.into_any().unbind())
    }
    let mut arrays = Vec::with_capacity(chain.len());
    for level in chain {
        arrays.push(match output {
            OutputKind::F32 => {
                let (w, h) = (level.width, level.height);
                let flat: Vec<f32> = level.texels.into_iter().flatten().collect();
                PyArray1::from_vec(py, flat).reshape([h, w, 3])?.into_any().unbind()
            }
            OutputKind::U8 => rounded::<u8>(py, &level)?,
            OutputKind::U16 => rounded::<u16>(py, &level)?,
        });
    }
    PyList::new(py, arrays)
}

/// A chain of normals, the finest level first.
type Chain = Vec<MipLevel<[f32; 3]>>;

/// The fit chain of a 2-D array of heights of sample type `H`, its
/// borders settled as `normals` settles them.
fn fit_chain_typed<H: Stored>(
    heights: &Bound<'_, PyUntypedArray>,
    opts: &Options,
    choices: BorderChoices,
) -> PyResult<(Chain, usize, usize)> {
    let py = heights.py();
    let (h, w) = (heights.shape()[0], heights.shape()[1]);
    let source = heights.cast::<PyArray2<H>>()?.try_readonly().map_err(borrow_error)?;
    let values = row_order(&source.as_array()).map_err(to_py_err)?;
    py.detach(|| -> Result<_, Error> {
        let borders = choices.settle(&values, w, h)?;
        let opts = opts.clone().with_borders(borders);
        Ok((normalfit::mips::fit_chain(&values, (w, h), &opts)?, w, h))
    })
    .map_err(to_py_err)
}

/// The unit normals of a (rows, columns, 3) array: floats n itself,
/// integers the encoded (n + 1)/2 read back as a normal map file is
/// (c = v / max as f32, then the library's
/// `normal_map::decode_planes`: n = 2c − 1).
fn normals_of<T: Element + Copy>(
    normals: &Bound<'_, PyUntypedArray>,
    planes: impl Fn(Vec<T>) -> Samples,
    signed: bool,
) -> PyResult<(Vec<[f32; 3]>, usize, usize)> {
    let shape = normals.shape();
    let (h, w) = (shape[0], shape[1]);
    if shape[2] != 3 {
        return Err(PyValueError::new_err(format!("normals must have shape (rows, columns, 3), got {shape:?}")));
    }
    let source = normals.cast::<PyArray3<T>>()?.try_readonly().map_err(borrow_error)?;
    let view = source.as_array();
    let mut channels = Vec::with_capacity(3);
    for c in 0..3 {
        let plane: Vec<T> = (0..h).flat_map(|y| (0..w).map(move |x| (y, x))).map(|(y, x)| view[[y, x, c]]).collect();
        channels.push(planes(plane).to_f32().map_err(to_py_err)?);
    }
    let planes = [&channels[0][..], &channels[1][..], &channels[2][..]];
    let normals = normalfit::normal_map::decode_planes(planes, signed).map_err(to_py_err)?;
    Ok((normals, w, h))
}

/// `mips` with every argument given (see `normalfit.mips`).
#[pyfunction]
#[allow(clippy::too_many_arguments)]
#[pyo3(signature = (array, way, patch, fit, border, convention, scale, relief, invert, dtype, roughness, roughness_base))]
fn mips<'py>(
    py: Python<'py>,
    array: &Bound<'py, PyAny>,
    way: &str,
    patch: &Bound<'py, PyAny>,
    fit: &str,
    border: &Bound<'py, PyAny>,
    convention: &str,
    scale: Option<f64>,
    relief: Option<f64>,
    invert: bool,
    dtype: &Bound<'py, PyAny>,
    roughness: bool,
    roughness_base: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyAny>> {
    let way: MipChoice = parse_named(way)?;
    let output = output_kind(py, dtype)?;
    let (opts, borders) = fit_options(patch, fit, border, convention, scale, relief, invert)?;
    let array = as_array(array, "array", &[2, 3])?;
    let kind = sample_kind(array, "array")?;
    let average = match (way, array.ndim()) {
        (MipChoice::Fit, 3) => {
            return Err(PyValueError::new_err(
                "invalid option: a (rows, columns, 3) array is a normal map: a fitted chain needs heights (way=\"average\")",
            ));
        }
        (MipChoice::Average, 2) => {
            return Err(PyValueError::new_err(
                "invalid option: way=\"average\" takes normals, a (rows, columns, 3) array: heights take way=\"fit\"",
            ));
        }
        (_, n) => n == 3,
    };
    let (chain, w, h) = if average {
        let (normals, w, h) = match kind {
            SampleKind::U8 => normals_of::<u8>(array, Samples::U8, false),
            SampleKind::U16 => normals_of::<u16>(array, Samples::U16, false),
            SampleKind::F32 => normals_of::<f32>(array, Samples::F32, true),
            SampleKind::F64 => normals_of::<f64>(array, Samples::F64, true),
        }?;
        (py.detach(|| normalfit::mips::average_chain(&normals, (w, h))).map_err(to_py_err)?, w, h)
    } else {
        match kind {
            SampleKind::U8 => fit_chain_typed::<u8>(array, &opts, borders),
            SampleKind::U16 => fit_chain_typed::<u16>(array, &opts, borders),
            SampleKind::F32 => fit_chain_typed::<f32>(array, &opts, borders),
            SampleKind::F64 => fit_chain_typed::<f64>(array, &opts, borders),
        }?
    };
    let rough = if roughness || roughness_base.is_some() {
        let base = match roughness_base {
            Some(base) => {
                let base = as_array(base, "roughness_base", &[2])?;
                if base.shape() != [h, w] {
                    return Err(PyValueError::new_err(format!(
                        "invalid option: roughness_base is {:?}, the input ({h}, {w}): a base roughness has the input's size",
                        base.shape()
                    )));
                }
                let values = match sample_kind(base, "roughness_base")? {
                    SampleKind::U8 => {
                        Samples::U8(row_order(&base.cast::<PyArray2<u8>>()?.readonly().as_array()).map_err(to_py_err)?)
                    }
                    SampleKind::U16 => Samples::U16(
                        row_order(&base.cast::<PyArray2<u16>>()?.readonly().as_array()).map_err(to_py_err)?,
                    ),
                    SampleKind::F32 => Samples::F32(
                        row_order(&base.cast::<PyArray2<f32>>()?.readonly().as_array()).map_err(to_py_err)?,
                    ),
                    SampleKind::F64 => Samples::F64(
                        row_order(&base.cast::<PyArray2<f64>>()?.readonly().as_array()).map_err(to_py_err)?,
                    ),
                };
                Some(values.to_f32().map_err(to_py_err)?)
            }
            None => None,
        };
        let finest = &chain[0].texels;
        let levels = py
            .detach(|| {
                normalfit::mips::mean_lengths(finest, (w, h))
                    .and_then(|l| normalfit::mips::roughness_chain(&l, base.as_deref()))
            })
            .map_err(to_py_err)?;
        let mut arrays = Vec::with_capacity(levels.len());
        for level in levels {
            arrays.push(PyArray1::from_vec(py, level.texels).reshape([level.height, level.width])?.into_any().unbind());
        }
        Some(PyList::new(py, arrays)?)
    } else {
        None
    };
    let levels = levels_as_arrays(py, chain, output)?;
    match rough {
        Some(r) => Ok(PyTuple::new(py, [levels.into_any(), r.into_any()])?.into_any()),
        None => Ok(levels.into_any()),
    }
}

/// `normals` with every argument given (see `normalfit.normals`).
#[pyfunction]
#[allow(clippy::too_many_arguments)]
#[pyo3(signature = (heights, patch, fit, border, convention, scale, relief, invert, dtype, residual, out, threads, units, pixel_size, nodata, detail=None, weights="uniform", product=None, slope_units="degrees", zero_for_flat=false, azimuth=315.0, altitude=45.0, transform=None))]
fn normals<'py>(
    py: Python<'py>,
    heights: &Bound<'py, PyAny>,
    patch: &Bound<'py, PyAny>,
    fit: &str,
    border: &Bound<'py, PyAny>,
    convention: &str,
    scale: Option<f64>,
    relief: Option<f64>,
    invert: bool,
    dtype: &Bound<'py, PyAny>,
    residual: bool,
    out: Option<&Bound<'py, PyAny>>,
    threads: Option<&Bound<'py, PyAny>>,
    units: &str,
    pixel_size: Option<&Bound<'py, PyAny>>,
    nodata: Option<f64>,
    detail: Option<&Bound<'py, PyAny>>,
    weights: &str,
    product: Option<&str>,
    slope_units: &str,
    zero_for_flat: bool,
    azimuth: f64,
    altitude: f64,
    transform: Option<[f64; 6]>,
) -> PyResult<Bound<'py, PyAny>> {
    let heights = as_array(heights, "heights", &[2])?;
    let kind = sample_kind(heights, "heights")?;
    let (opts, borders) = fit_options(patch, fit, border, convention, scale, relief, invert)?;
    let mut opts = with_weights(with_detail(opts, detail)?, weights)?;
    if let Some(units) = array_units(units, pixel_size, heights.shape()[0])? {
        opts = opts.with_units(units);
    }
    let opts = opts.with_nodata(nodata);
    let terrain = terrain_of(product, slope_units, zero_for_flat, (azimuth, altitude), transform)?;
    let output = output_kind(py, dtype)?;
    if terrain.is_none() {
        check_nodata_output(nodata, output)?;
    }
    let call = Call { opts: &opts, borders, out, residual, pool: pool(threads)?, window: None };
    match terrain {
        Some(terrain) => terrain_call(heights, kind, &call, terrain),
        None => fit_call(heights, kind, output, &call),
    }
}

/// A terrain product asked for by `normals`' `product=` and its options:
/// a slope or aspect map, or the hillshade.
#[derive(Clone, Copy)]
enum Terrain {
    Measure(Measure, Option<Affine>),
    Hillshade(Sun, Option<Affine>),
}

/// `product=` ("slope", "aspect", "hillshade" or None for the normals)
/// and its options, checked by the library's parsers.
fn terrain_of(
    product: Option<&str>,
    slope_units: &str,
    zero_for_flat: bool,
    (azimuth, altitude): (f64, f64),
    transform: Option<[f64; 6]>,
) -> PyResult<Option<Terrain>> {
    // GDAL's order: x of the corner, x per column, x per row, y of the
    // corner, y per column, y per row.
    let affine = transform.map(|[c, a, b, f, d, e]| Affine { a, b, c, d, e, f });
    let Some(product) = product else {
        if affine.is_some() {
            let problem = "transform= places a slope, aspect or hillshade on the map; normals are in the image's frame";
            return Err(PyValueError::new_err(format!("invalid option: {problem}")));
        }
        return Ok(None);
    };
    Ok(match parse_named::<Product>(product)? {
        Product::Slope => Some(Terrain::Measure(Measure::Slope(parse_named::<SlopeUnits>(slope_units)?), affine)),
        Product::Aspect => Some(Terrain::Measure(Measure::Aspect { zero_for_flat }, affine)),
        Product::Hillshade => Some(Terrain::Hillshade(Sun::new(azimuth, altitude).map_err(to_py_err)?, affine)),
        other => {
            return Err(PyValueError::new_err(format!(
                "invalid option: product of the terrain functions is slope, aspect or hillshade, got {other}"
            )));
        }
    })
}

/// [`terrain_typed`] for the heights' sample type.
fn terrain_call<'py>(
    heights: &Bound<'py, PyUntypedArray>,
    kind: SampleKind,
    call: &Call<'_, 'py>,
    terrain: Terrain,
) -> PyResult<Bound<'py, PyAny>> {
    if call.residual || call.out.is_some() {
        return Err(PyValueError::new_err("a slope, aspect or hillshade takes no residual and no out="));
    }
    match kind {
        SampleKind::U8 => terrain_typed::<u8>(heights, call, terrain),
        SampleKind::U16 => terrain_typed::<u16>(heights, call, terrain),
        SampleKind::F32 => terrain_typed::<f32>(heights, call, terrain),
        SampleKind::F64 => terrain_typed::<f64>(heights, call, terrain),
    }
}

/// A slope or aspect map (float32, NaN at holes) or a hillshade (uint8,
/// 0 at holes) of the heights, or of the window they hold: the library's
/// `products::measure_into` and `hillshade_into`, the command line's
/// values.
fn terrain_typed<'py, H: Stored>(
    heights: &Bound<'py, PyUntypedArray>,
    call: &Call<'_, 'py>,
    terrain: Terrain,
) -> PyResult<Bound<'py, PyAny>> {
    let py = heights.py();
    let (h, w) = (heights.shape()[0], heights.shape()[1]);
    let (ow, oh) = call.window.map_or((w, h), |win| win.size);
    let source = heights.cast::<PyArray2<H>>()?.try_readonly().map_err(borrow_error)?;
    let in_place = if heights.is_c_contiguous() { source.as_slice().ok() } else { None };
    let view = source.as_array();
    let out = match terrain {
        Terrain::Measure(..) => empty(py, &[oh, ow], dtype::<f32>(py))?,
        Terrain::Hillshade(..) => empty(py, &[oh, ow], dtype::<u8>(py))?,
    };
    let (choices, pool, window) = (call.borders, call.pool.as_ref().and_then(|b| b.pool.as_ref()), call.window);
    let opts = call.opts;
    let run = |out_f32: Option<&mut [f32]>, out_u8: Option<&mut [u8]>| {
        py.detach(|| -> Result<(), Error> {
            let heights = in_row_order(in_place, &view)?;
            let heights: &[H] = &heights;
            let borders = match window {
                Some(_) => window_borders(choices)?,
                None => choices.settle(heights, w, h)?,
            };
            let mut request = FitRequest::new(opts).borders(borders);
            if let Some(window) = window {
                request = request.window(window);
            }
            on_pool(pool, || match (terrain, out_f32, out_u8) {
                (Terrain::Measure(m, affine), Some(out), _) => {
                    measure_into(request, m, affine.as_ref(), f32::NAN, heights, w, h, out)
                }
                (Terrain::Hillshade(sun, affine), _, Some(out)) => {
                    hillshade_into(request, sun, affine.as_ref(), heights, w, h, out)
                }
                _ => Err(Error::InvalidOption("the output's type is not the product's".into())),
            })
            .map(|_missing| ())
        })
        .map_err(to_py_err)
    };
    match terrain {
        Terrain::Measure(..) => {
            let array = out.cast::<PyArray2<f32>>()?;
            let mut rw = array.try_readwrite().map_err(borrow_error)?;
            let flat = rw.as_slice_mut().map_err(|e| PyValueError::new_err(format!("out: {e}")))?;
            run(Some(flat), None)?;
        }
        Terrain::Hillshade(..) => {
            let array = out.cast::<PyArray2<u8>>()?;
            let mut rw = array.try_readwrite().map_err(borrow_error)?;
            let flat = rw.as_slice_mut().map_err(|e| PyValueError::new_err(format!("out: {e}")))?;
            run(None, Some(flat))?;
        }
    }
    Ok(out)
}

/// Holes need float32 normals: a missing texel's normal is NaN, the NumPy
/// convention for a missing value, which integer texels cannot hold.
fn check_nodata_output(nodata: Option<f64>, output: OutputKind) -> PyResult<()> {
    match (nodata, output) {
        (Some(_), OutputKind::U8 | OutputKind::U16) => Err(PyValueError::new_err(
            "nodata needs dtype float32: a missing texel's normal is NaN, which integers cannot hold",
        )),
        _ => Ok(()),
    }
}

/// `curvature` with every argument given (see `normalfit.curvature`):
/// the library's `normalfit::curvature`, float32 (rows, columns).
#[pyfunction]
#[allow(clippy::too_many_arguments)]
#[pyo3(signature = (heights, patch, border, scale, relief, invert, threads, units, pixel_size, nodata))]
fn curvature<'py>(
    heights: &Bound<'py, PyAny>,
    patch: &Bound<'py, PyAny>,
    border: &Bound<'py, PyAny>,
    scale: Option<f64>,
    relief: Option<f64>,
    invert: bool,
    threads: Option<&Bound<'py, PyAny>>,
    units: &str,
    pixel_size: Option<&Bound<'py, PyAny>>,
    nodata: Option<f64>,
) -> PyResult<Bound<'py, PyAny>> {
    let heights = as_array(heights, "heights", &[2])?;
    let kind = sample_kind(heights, "heights")?;
    let (mut opts, borders) = fit_options(patch, "orthogonal", border, "opengl", scale, relief, invert)?;
    if let Some(units) = array_units(units, pixel_size, heights.shape()[0])? {
        opts = opts.with_units(units);
    }
    let opts = opts.with_nodata(nodata);
    let pool = pool(threads)?;
    match kind {
        SampleKind::U8 => curvature_typed::<u8>(heights, &opts, borders, pool),
        SampleKind::U16 => curvature_typed::<u16>(heights, &opts, borders, pool),
        SampleKind::F32 => curvature_typed::<f32>(heights, &opts, borders, pool),
        SampleKind::F64 => curvature_typed::<f64>(heights, &opts, borders, pool),
    }
}

/// [`curvature`] for the heights' sample type: read in place when the
/// array is C-contiguous, `auto` borders settled by the tiling check.
fn curvature_typed<'py, H: Stored>(
    heights: &Bound<'py, PyUntypedArray>,
    opts: &Options,
    choices: BorderChoices,
    pool: Option<Borrowed>,
) -> PyResult<Bound<'py, PyAny>> {
    let py = heights.py();
    let (h, w) = (heights.shape()[0], heights.shape()[1]);
    let source = heights.cast::<PyArray2<H>>()?.try_readonly().map_err(borrow_error)?;
    let in_place = if heights.is_c_contiguous() { source.as_slice().ok() } else { None };
    let view = source.as_array();
    let pool = pool.as_ref().and_then(|b| b.pool.as_ref());
    let values = py
        .detach(|| -> Result<Vec<f32>, Error> {
            let heights = in_row_order(in_place, &view)?;
            let heights: &[H] = &heights;
            let borders = choices.settle(heights, w, h)?;
            let opts = opts.clone().with_borders(borders);
            on_pool(pool, || normalfit::curvature(heights, w, h, &opts))
        })
        .map_err(to_py_err)?;
    Ok(PyArray1::from_vec(py, values).reshape([h, w])?.into_any())
}

/// [`fit_typed`] for the heights' sample type and the output's.
fn fit_call<'py>(
    heights: &Bound<'py, PyUntypedArray>,
    kind: SampleKind,
    output: OutputKind,
    call: &Call<'_, 'py>,
) -> PyResult<Bound<'py, PyAny>> {
    macro_rules! typed {
        ($h:ty) => {
            match output {
                OutputKind::F32 => fit_typed::<$h, f32>(heights, call),
                OutputKind::U8 => fit_typed::<$h, u8>(heights, call),
                OutputKind::U16 => fit_typed::<$h, u16>(heights, call),
            }
        };
    }
    match kind {
        SampleKind::U8 => typed!(u8),
        SampleKind::U16 => typed!(u16),
        SampleKind::F32 => typed!(f32),
        SampleKind::F64 => typed!(f64),
    }
}

/// The borders of a window: fixed modes, since `auto` is the tiling check
/// of the whole image, which a window does not hold.
fn window_borders(choices: BorderChoices) -> Result<normalfit::Borders, Error> {
    if choices.any_auto() {
        return Err(Error::InvalidOption(
            "border auto needs the whole image's tiling check, which a window does not hold: settle it first \
             (normalfit.dask.check_tiling(array).suggested_borders) and pass the modes"
                .into(),
        ));
    }
    choices.fixed()
}

/// `window_normals` with every argument given: the normals of a window of
/// an image, from the window's heights and the halo held around it (the
/// library's `FitRequest` with a `window`; `normalfit.dask` calls it on each
/// chunk). `heights` is the window and its halo; `image` the whole image's
/// (width, height), `origin` the window's first (column, row), `halo`
/// (left, right, top, bottom). The options are `normals`'s (no `out`).
#[pyfunction]
#[allow(clippy::too_many_arguments)]
#[pyo3(signature = (heights, image, origin, halo, patch, fit, border, convention, scale, relief, invert, dtype, residual, threads, nodata=None, detail=None, units="texels", pixel_size=None, weights="uniform", product=None, slope_units="degrees", zero_for_flat=false, azimuth=315.0, altitude=45.0, transform=None))]
fn window_normals<'py>(
    py: Python<'py>,
    heights: &Bound<'py, PyAny>,
    image: (usize, usize),
    origin: (usize, usize),
    halo: (usize, usize, usize, usize),
    patch: &Bound<'py, PyAny>,
    fit: &str,
    border: &Bound<'py, PyAny>,
    convention: &str,
    scale: Option<f64>,
    relief: Option<f64>,
    invert: bool,
    dtype: &Bound<'py, PyAny>,
    residual: bool,
    threads: Option<&Bound<'py, PyAny>>,
    nodata: Option<f64>,
    detail: Option<&Bound<'py, PyAny>>,
    units: &str,
    pixel_size: Option<&Bound<'py, PyAny>>,
    weights: &str,
    product: Option<&str>,
    slope_units: &str,
    zero_for_flat: bool,
    azimuth: f64,
    altitude: f64,
    transform: Option<[f64; 6]>,
) -> PyResult<Bound<'py, PyAny>> {
    let heights = as_array(heights, "heights", &[2])?;
    let kind = sample_kind(heights, "heights")?;
    let (opts, borders) = fit_options(patch, fit, border, convention, scale, relief, invert)?;
    let mut opts = with_weights(with_detail(opts, detail)?, weights)?;
    // The whole image's spacing: a window's rows take their image row's.
    if let Some(units) = array_units(units, pixel_size, image.1)? {
        opts = opts.with_units(units);
    }
    let opts = opts.with_nodata(nodata);
    let terrain = terrain_of(product, slope_units, zero_for_flat, (azimuth, altitude), transform)?;
    let output = output_kind(py, dtype)?;
    if terrain.is_none() {
        check_nodata_output(nodata, output)?;
    }
    let (left, right, top, bottom) = halo;
    let (held_h, held_w) = (heights.shape()[0], heights.shape()[1]);
    let size =
        (held_w.checked_sub(left + right).filter(|&w| w > 0), held_h.checked_sub(top + bottom).filter(|&h| h > 0));
    let (Some(w), Some(h)) = size else {
        return Err(PyValueError::new_err(format!(
            "heights of {held_h} rows and {held_w} columns hold no window inside a halo of {left} left, {right} \
             right, {top} top, {bottom} bottom"
        )));
    };
    let window = Window { image, origin, size: (w, h), halo: Halo { left, right, top, bottom } };
    let call = Call { opts: &opts, borders, out: None, residual, pool: pool(threads)?, window: Some(window) };
    match terrain {
        Some(terrain) => terrain_call(heights, kind, &call, terrain),
        None => fit_call(heights, kind, output, &call),
    }
}

/// What `normalfit.dask.normals` asks before it makes a graph: the
/// options of `window_normals` checked as a window's fit checks them,
/// without fitting (the image's `(width, height)`, refused without
/// texels as the whole-array fit refuses it, the heights' dtype, every option, the output dtype,
/// `threads`, border `auto`'s refusal), and the library's halo plan for
/// them (`fit::HaloPlan`): the most a chunk's halo reaches on a side
/// (`HaloPlan::reach`: r, or more with binomial weights summed by blocks), and
/// whether along x and along y a chunk at the image's edge holds a halo
/// beyond it (wrap: Dask's `periodic` boundary; clamp and mirror hold none).
#[pyfunction]
#[allow(clippy::too_many_arguments)]
#[pyo3(signature = (image, heights_dtype, patch, fit, border, convention, scale, relief, invert, dtype, threads, nodata=None, detail=None, units="texels", pixel_size=None, weights="uniform"))]
fn window_plan(
    py: Python<'_>,
    image: (usize, usize),
    heights_dtype: &Bound<'_, PyAny>,
    patch: &Bound<'_, PyAny>,
    fit: &str,
    border: &Bound<'_, PyAny>,
    convention: &str,
    scale: Option<f64>,
    relief: Option<f64>,
    invert: bool,
    dtype: &Bound<'_, PyAny>,
    threads: Option<&Bound<'_, PyAny>>,
    nodata: Option<f64>,
    detail: Option<&Bound<'_, PyAny>>,
    units: &str,
    pixel_size: Option<&Bound<'_, PyAny>>,
    weights: &str,
) -> PyResult<(usize, (bool, bool))> {
    normalfit::fit::checked_len(image.0, image.1).map_err(to_py_err)?;
    sample_kind_of(&PyArrayDescr::new(py, heights_dtype)?, "heights")?;
    let (opts, borders) = fit_options(patch, fit, border, convention, scale, relief, invert)?;
    let mut opts = with_weights(with_detail(opts, detail)?, weights)?;
    if let Some(units) = array_units(units, pixel_size, image.1)? {
        opts = opts.with_units(units);
    }
    check_nodata_output(nodata, output_kind(py, dtype)?)?;
    thread_count(threads)?;
    let borders = window_borders(borders).map_err(to_py_err)?;
    let plan = HaloPlan::new(&opts.with_borders(borders)).map_err(to_py_err)?;
    Ok((plan.reach(), plan.beyond_edges()))
}

/// The halo (left, right, top, bottom) the library plans for the window
/// of `size` (width, height) at `origin` (column, row) of an image of
/// `image` (width, height) texels, for a patch of `patch` and `border`'s
/// modes (`fit::HaloPlan::halo`): what `normalfit.dask` holds around each
/// chunk.
#[pyfunction]
#[pyo3(signature = (image, origin, size, patch, border, detail=None, weights="uniform"))]
fn window_halo(
    image: (usize, usize),
    origin: (usize, usize),
    size: (usize, usize),
    patch: &Bound<'_, PyAny>,
    border: &Bound<'_, PyAny>,
    detail: Option<&Bound<'_, PyAny>>,
    weights: &str,
) -> PyResult<(usize, usize, usize, usize)> {
    let patch = whole(patch, "patch")?;
    let Ok(patch) = usize::try_from(patch) else {
        return Err(PyValueError::new_err(format!(
            "invalid option: patch size must be odd and at least 3, got {patch}"
        )));
    };
    let borders = window_borders(parse_borders(border)?).map_err(to_py_err)?;
    let opts = with_weights(with_detail(Options::new().with_patch(patch).with_borders(borders), detail)?, weights)?;
    let Halo { left, right, top, bottom } = HaloPlan::new(&opts).map_err(to_py_err)?.halo(image, origin, size);
    Ok((left, right, top, bottom))
}

/// `border=` as the library parses it: the (x, y) modes' names, `"auto"`
/// for an axis left to the tiling check. `normalfit.dask` picks each
/// axis's Dask boundary from them.
#[pyfunction]
fn border_names(border: &Bound<'_, PyAny>) -> PyResult<(&'static str, &'static str)> {
    let choices = parse_borders(border)?;
    let name = |c: BorderChoice| match c {
        BorderChoice::Fixed(b) => Border::name(b),
        BorderChoice::Auto => "auto",
    };
    Ok((name(choices.x), name(choices.y)))
}

/// What the output texels are.
#[derive(Clone, Copy, Debug)]
enum OutputKind {
    /// The unit normal.
    F32,
    /// The contract's 8-bit RGB.
    U8,
    /// The contract's 16-bit RGB.
    U16,
}

/// `dtype=`: anything `numpy.dtype` takes that means float32, uint8 or uint16.
fn output_kind(py: Python<'_>, dt: &Bound<'_, PyAny>) -> PyResult<OutputKind> {
    let bad =
        || PyValueError::new_err(format!("invalid option: dtype must be float32, uint8 or uint16, got {}", shown(dt)));
    let descr = PyArrayDescr::new(py, dt).map_err(|_| bad())?;
    for (kind, candidate) in
        [(OutputKind::F32, dtype::<f32>(py)), (OutputKind::U8, dtype::<u8>(py)), (OutputKind::U16, dtype::<u16>(py))]
    {
        if descr.is_equiv_to(&candidate) {
            return Ok(kind);
        }
    }
    Err(bad())
}

/// One axis of a tiling report: the `--json` output's `x` or `y`.
#[pyclass(frozen, get_all, module = "normalfit")]
#[derive(Clone)]
struct AxisReport {
    /// How the wrap pair compares with the interior pairs: about 1 or less
    /// when it looks like them, larger for a more visible seam.
    score: f64,
    /// ``score <= threshold``.
    seamless: bool,
}

#[pymethods]
impl AxisReport {
    fn __repr__(&self) -> String {
        format!("AxisReport(score={}, seamless={})", py_float(self.score), py_bool(self.seamless))
    }
}

/// The tiling check's verdict on an array: the fields of `normalfit tiling
/// --json` (kind, x, y, seamless, width, height) and the borders `auto`
/// would pick.
#[pyclass(frozen, get_all, module = "normalfit")]
struct TilingReport {
    /// ``"height"`` or ``"normal"``: what the array was judged as.
    kind: &'static str,
    /// The x seam: last column against first.
    x: Py<AxisReport>,
    /// The y seam: last row against first.
    y: Py<AxisReport>,
    /// Whether the array tiles on both axes.
    seamless: bool,
    /// Columns.
    width: usize,
    /// Rows.
    height: usize,
    /// Wrap on the axes that tile, mirror on the others, as ``(x, y)``:
    /// the borders ``border="auto"`` takes.
    suggested_borders: (&'static str, &'static str),
}

#[pymethods]
impl TilingReport {
    fn __repr__(&self) -> String {
        format!(
            "TilingReport(kind='{}', x={}, y={}, seamless={}, width={}, height={})",
            self.kind,
            self.x.get().__repr__(),
            self.y.get().__repr__(),
            py_bool(self.seamless),
            self.width,
            self.height
        )
    }
}

/// A float as Python's `repr` shows it (shortest round trip).
fn py_float(v: f64) -> String {
    if v.is_finite() && v == v.trunc() && v.abs() < 1e16 { format!("{v:.1}") } else { format!("{v}") }
}

fn py_bool(b: bool) -> &'static str {
    if b { "True" } else { "False" }
}

/// One plane of an array in the contract's units, as f32: the library's
/// conversion of stored samples ([`Samples::into_f32`]).
fn plane_f32<H: Element + Copy>(view: ArrayView2<'_, H>, wrap: fn(Vec<H>) -> Samples) -> Result<Vec<f32>, Error> {
    wrap(row_order(&view)?).into_f32()
}

/// The planes of a 2-D (H, W) or 3-D (H, W, C) array, C from 1 to 4.
fn planes_typed<H: Element + Copy>(
    array: &Bound<'_, PyUntypedArray>,
    wrap: fn(Vec<H>) -> Samples,
) -> PyResult<Vec<Vec<f32>>> {
    let py = array.py();
    let shape = array.shape().to_vec();
    let planes = if shape.len() == 2 {
        let source = array.cast::<PyArray2<H>>()?.try_readonly().map_err(borrow_error)?;
        let view = source.as_array();
        py.detach(|| plane_f32(view, wrap).map(|p| vec![p]))
    } else {
        let source = array.cast::<PyArray3<H>>()?.try_readonly().map_err(borrow_error)?;
        let view = source.as_array();
        py.detach(|| {
            (0..shape[2])
                .map(|c| plane_f32(view.index_axis(numpy::ndarray::Axis(2), c), wrap))
                .collect::<Result<Vec<_>, Error>>()
        })
    };
    planes.map_err(to_py_err)
}

/// `check_tiling` with every argument given (see `normalfit.check_tiling`).
#[pyfunction]
#[pyo3(signature = (image, threshold, kind))]
fn check_tiling(py: Python<'_>, image: &Bound<'_, PyAny>, threshold: f64, kind: &str) -> PyResult<TilingReport> {
    let array = as_array(image, "image", &[2, 3])?;
    let shape = array.shape().to_vec();
    if shape.len() == 3 && !(1..=4).contains(&shape[2]) {
        return Err(PyTypeError::new_err(format!(
            "image must be (height, width) or (height, width, channels) with 1 to 4 channels, got {} channels",
            shape[2]
        )));
    }
    let opts = tiling_options(threshold, kind)?;
    let planes = match sample_kind(array, "image")? {
        SampleKind::U8 => planes_typed::<u8>(array, Samples::U8)?,
        SampleKind::U16 => planes_typed::<u16>(array, Samples::U16)?,
        SampleKind::F32 => planes_typed::<f32>(array, Samples::F32)?,
        SampleKind::F64 => planes_typed::<f64>(array, Samples::F64)?,
    };
    let (height, width) = (shape[0], shape[1]);
    let report = py
        .detach(|| {
            let refs: Vec<&[f32]> = planes.iter().map(Vec::as_slice).collect();
            tiling::check(&refs, width, height, &opts)
        })
        .map_err(to_py_err)?;
    tiling_report_value(py, &report, width, height)
}

/// The tiling check of a height map fed a block of rows at a time, top to
/// bottom: the library's `tiling::HeightSeams`, which `border="auto"`
/// settles borders with. Fed whole rows (`push`), or only the lines the
/// check reads (`push_columns` with each row's `edge_columns`, `push_rows`
/// with the `edge_rows`): `normalfit.dask.check_tiling` feeds it those
/// strips of a Dask array, so that only the chunks at the edges are
/// computed and the client holds O(W + H) of the check and one block of a
/// strip, never the array.
#[pyclass(module = "normalfit", name = "_HeightSeams")]
struct PyHeightSeams {
    seams: Mutex<Option<tiling::HeightSeams>>,
    width: usize,
    height: usize,
}

/// Which of the check's ways of taking heights a push uses.
#[derive(Clone, Copy)]
enum SeamsPush {
    Rows,
    EdgeColumns,
    EdgeRows,
}

impl PyHeightSeams {
    /// Pushes a 2-D array of heights through `how`, the library checking
    /// the counts; `columns` is the width its rows must have.
    fn push_with(&self, rows: &Bound<'_, PyAny>, columns: usize, how: SeamsPush) -> PyResult<()> {
        let array = as_array(rows, "rows", &[2])?;
        if array.shape()[1] != columns {
            return Err(PyValueError::new_err(format!("rows must have {columns} columns, got {}", array.shape()[1])));
        }
        fn typed<H: Stored>(
            array: &Bound<'_, PyUntypedArray>,
            seams: &mut tiling::HeightSeams,
            how: SeamsPush,
        ) -> PyResult<()> {
            let source = array.cast::<PyArray2<H>>()?.try_readonly().map_err(borrow_error)?;
            let view = source.as_array();
            array
                .py()
                .detach(|| {
                    let rows = row_order(&view)?;
                    match how {
                        SeamsPush::Rows => seams.push_heights(&rows),
                        SeamsPush::EdgeColumns => seams.push_edge_columns(&rows),
                        SeamsPush::EdgeRows => seams.push_edge_rows(&rows),
                    }
                })
                .map_err(to_py_err)
        }
        let mut guard = self.seams.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        let Some(seams) = guard.as_mut() else {
            return Err(PyValueError::new_err("the tiling check is finished already"));
        };
        match sample_kind(array, "rows")? {
            SampleKind::U8 => typed::<u8>(array, seams, how),
            SampleKind::U16 => typed::<u16>(array, seams, how),
            SampleKind::F32 => typed::<f32>(array, seams, how),
            SampleKind::F64 => typed::<f64>(array, seams, how),
        }
    }

    /// A property of the check, while it is not finished.
    fn with_seams<T>(&self, f: impl FnOnce(&tiling::HeightSeams) -> T) -> PyResult<T> {
        let guard = self.seams.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        guard.as_ref().map(f).ok_or_else(|| PyValueError::new_err("the tiling check is finished already"))
    }
}

/// Two ranges as ((start, stop), (start, stop)).
type RangePair = ((usize, usize), (usize, usize));

fn range_pair([a, b]: [std::ops::Range<usize>; 2]) -> RangePair {
    ((a.start, a.end), (b.start, b.end))
}

#[pymethods]
impl PyHeightSeams {
    /// `refuse_non_finite`: a NaN or infinite height among the lines read
    /// raises ValueError naming its texel (else it is a hole). `nodata`:
    /// the stored value whose texels are holes, skipped by the check.
    #[new]
    #[pyo3(signature = (width, height, refuse_non_finite = false, nodata = None))]
    fn new(width: usize, height: usize, refuse_non_finite: bool, nodata: Option<f64>) -> PyResult<Self> {
        let seams = tiling::HeightSeams::new(width, height).map_err(to_py_err)?.with_nodata(nodata);
        let seams = if refuse_non_finite { seams.refusing_non_finite() } else { seams };
        Ok(PyHeightSeams { seams: Mutex::new(Some(seams)), width, height })
    }

    /// Adds the next whole rows: a 2-D (rows, width) array of uint8,
    /// uint16, float32 or float64 heights (integers divided by 255 or
    /// 65535).
    fn push(&self, rows: &Bound<'_, PyAny>) -> PyResult<()> {
        self.push_with(rows, self.width, SeamsPush::Rows)
    }

    /// The columns of every row the check reads: ((start, stop), (start,
    /// stop)), the second empty when the first is the whole row.
    #[getter]
    fn edge_columns(&self) -> PyResult<RangePair> {
        self.with_seams(|s| range_pair(s.edge_columns()))
    }

    /// The rows `push_rows` takes, whole: ((start, stop), (start, stop)),
    /// both empty when `edge_columns` is the whole row.
    #[getter]
    fn edge_rows(&self) -> PyResult<RangePair> {
        self.with_seams(|s| range_pair(s.edge_rows()))
    }

    /// Adds the edge columns of the next rows: a 2-D array whose columns
    /// are those of `edge_columns`, first range then second.
    fn push_columns(&self, rows: &Bound<'_, PyAny>) -> PyResult<()> {
        let columns = self.with_seams(|s| s.edge_columns().iter().map(|r| r.len()).sum())?;
        self.push_with(rows, columns, SeamsPush::EdgeColumns)
    }

    /// Adds the next of the `edge_rows`, whole, in order.
    fn push_rows(&self, rows: &Bound<'_, PyAny>) -> PyResult<()> {
        self.push_with(rows, self.width, SeamsPush::EdgeRows)
    }

    /// The rows pushed so far (whole, or as edge columns).
    #[getter]
    fn rows(&self) -> usize {
        self.seams.lock().unwrap_or_else(std::sync::PoisonError::into_inner).as_ref().map_or(self.height, |s| s.rows())
    }

    /// The report, judged as a height map with this threshold; once only.
    fn finish(&self, py: Python<'_>, threshold: f64) -> PyResult<TilingReport> {
        let opts = tiling_options(threshold, "height")?;
        let seams = self.seams.lock().unwrap_or_else(std::sync::PoisonError::into_inner).take();
        let Some(seams) = seams else {
            return Err(PyValueError::new_err("the tiling check is finished already"));
        };
        let report = py.detach(|| seams.finish(&opts)).map_err(to_py_err)?;
        tiling_report_value(py, &report, self.width, self.height)
    }
}

/// The tiling check's options, checked by the library as the command line's
/// are.
fn tiling_options(threshold: f64, kind: &str) -> PyResult<TilingOptions> {
    let opts = TilingOptions::new().with_threshold(threshold).with_kind(parse_named(kind)?);
    opts.validate().map_err(to_py_err)?;
    Ok(opts)
}

/// The library's report as the Python object.
fn tiling_report_value(
    py: Python<'_>,
    report: &tiling::TilingReport,
    width: usize,
    height: usize,
) -> PyResult<TilingReport> {
    let axis = |a: tiling::AxisReport| Py::new(py, AxisReport { score: a.score, seamless: a.seamless });
    let suggested = report.suggested_borders();
    Ok(TilingReport {
        kind: match report.kind {
            ImageKind::Height => "height",
            ImageKind::Normal => "normal",
        },
        x: axis(report.x)?,
        y: axis(report.y)?,
        seamless: report.seamless(),
        width,
        height,
        suggested_borders: (Border::name(suggested.x), Border::name(suggested.y)),
    })
}

/// [`tiling_report_value`] as a Python object.
fn tiling_report_object(
    py: Python<'_>,
    report: &tiling::TilingReport,
    width: usize,
    height: usize,
) -> PyResult<Py<TilingReport>> {
    Py::new(py, tiling_report_value(py, report, width, height)?)
}

/// A file API's error. `ValueError` for an option (and for an output the
/// options cannot make, such as 8-bit EXR), and for an input whose
/// extension names another format than its content, the file named;
/// `MemoryError` naming the file for one too large (for `max_texels`, or
/// for the memory the process may take: the command line's line); else
/// `OSError` naming the file: `OSError(errno, message, filename)` when the
/// system gave an errno (so a missing file is `FileNotFoundError`), else
/// the library's line after the file's name.
fn file_error(path: &Path, e: Error, output: bool) -> PyErr {
    let shown = path.display().to_string();
    match &e {
        Error::InvalidOption(_) | Error::Misnamed { .. } => PyValueError::new_err(format!("{shown}: {e}")),
        Error::Limits(_) => PyMemoryError::new_err(format!("{shown}: {e}")),
        Error::Unsupported(_) if output => PyValueError::new_err(format!("{shown}: {e}")),
        Error::Io(io) if io.raw_os_error().is_some() => PyOSError::new_err((io.raw_os_error(), e.to_string(), shown)),
        _ => PyOSError::new_err(format!("{shown}: {e}")),
    }
}

/// How files are read: the CLI's `--max-texels` and `--layer`.
fn read_options(max_texels: Option<&Bound<'_, PyAny>>, layer: Option<String>) -> PyResult<ReadOptions> {
    let mut read = ReadOptions::default();
    if let Some(n) = count(max_texels, "max_texels")? {
        read = read.with_max_texels(n);
    }
    if let Some(name) = layer {
        read = read.with_layer(name);
    }
    read.validate().map_err(to_py_err)?;
    Ok(read)
}

/// `units=` and `pixel_size=`: the map units they ask for, by the
/// library's rule (`--units`, `--pixel-size`).
fn map_units(units: &str, pixel_size: Option<(f64, f64)>) -> PyResult<Option<MapSpacing>> {
    Ok(MapSpacing::choose(parse_named::<UnitsName>(units)?, pixel_size.map(|(x, y)| [x, y])))
}

/// `pixel_size=` of an array's fit: an (x, y) pair, or one (x, y) per
/// image row as a (rows, 2) float64 array (a geographic raster's metres,
/// as `geotransform_spacing` gives them).
enum PixelSize {
    Pair(f64, f64),
    Rows(Vec<[f64; 2]>),
}

fn pixel_size_arg(obj: Option<&Bound<'_, PyAny>>) -> PyResult<Option<PixelSize>> {
    let Some(obj) = obj.filter(|o| !o.is_none()) else {
        return Ok(None);
    };
    if let Ok((x, y)) = obj.extract::<(f64, f64)>() {
        return Ok(Some(PixelSize::Pair(x, y)));
    }
    if let Ok(rows) = obj.cast::<PyArray2<f64>>()
        && rows.shape()[1] == 2
    {
        let rows = rows.try_readonly().map_err(borrow_error)?;
        let rows = rows.as_array().rows().into_iter().map(|r| [r[0], r[1]]).collect();
        return Ok(Some(PixelSize::Rows(rows)));
    }
    Err(PyTypeError::new_err(format!(
        "pixel_size must be (x, y) or a (rows, 2) float64 array of one (x, y) per row, got {}",
        shown(obj)
    )))
}

/// The units of an array's fit of `height` rows: `map_units`'s, or map
/// units with one spacing per row, checked by the library
/// (`Spacing::validate`: one per row, finite, positive).
fn array_units(units: &str, pixel_size: Option<&Bound<'_, PyAny>>, height: usize) -> PyResult<Option<Units>> {
    match pixel_size_arg(pixel_size)? {
        Some(PixelSize::Rows(rows)) => {
            let spacing = Spacing::Rows(rows.into());
            spacing.validate(Some(height)).map_err(to_py_err)?;
            Ok(Some(Units::Map(spacing)))
        }
        pair => {
            let pair = match pair {
                Some(PixelSize::Pair(x, y)) => Some((x, y)),
                _ => None,
            };
            // An array has no georeferencing: map units need the pixel
            // size (the library says so when it is missing).
            map_units(units, pair)?.map(|map| map.units(None, height).map_err(to_py_err)).transpose()
        }
    }
}

/// The spacing of a raster known by its GDAL geotransform (`transform`),
/// its coordinate system (`crs`: "projected" or "geographic" with the
/// EPSG code of its `unit`, or None) and its `height` in rows: the
/// library's `units::geotransform_spacing` (what `normalfit.xarray` fits a
/// DataArray with). An (x, y) pair, or for a geographic raster a
/// (height, 2) float64 array, one (x, y) per row, in metres.
#[pyfunction]
fn geotransform_spacing<'py>(
    py: Python<'py>,
    transform: [f64; 6],
    crs: Option<&str>,
    unit: Option<u16>,
    height: usize,
) -> PyResult<Bound<'py, PyAny>> {
    let unit_of = |what: &str| {
        unit.ok_or_else(|| PyValueError::new_err(format!("a {what} coordinate system needs the EPSG code of its unit")))
    };
    let crs = match crs {
        None => Crs::Unknown,
        Some("projected") => Crs::Projected { unit: unit_of("projected")? },
        Some("geographic") => Crs::Geographic { unit: unit_of("geographic")? },
        Some(other) => {
            return Err(PyValueError::new_err(format!("crs must be projected, geographic or None, got {other:?}")));
        }
    };
    let spacing = py.detach(|| normalfit::units::geotransform_spacing(transform, crs, height)).map_err(to_py_err)?;
    match spacing {
        Spacing::Uniform { x, y } => Ok(PyTuple::new(py, [x, y])?.into_any()),
        rows => {
            let flat: Vec<f64> = (0..height).flat_map(|r| rows.at(r)).collect();
            Ok(PyArray1::from_vec(py, flat).reshape([height, 2])?.into_any())
        }
    }
}

/// The GDAL geotransform of a north-up raster whose texel centres are at
/// `x` (columns) and `y` (rows): the library's
/// `units::centres_geotransform` (regular steps, else a ValueError).
#[pyfunction]
fn centres_geotransform(x: Vec<f64>, y: Vec<f64>) -> PyResult<[f64; 6]> {
    normalfit::units::centres_geotransform(&x, &y).map_err(to_py_err)
}

/// How terrain files are read, the CLI's `--band`, `--size`,
/// `--byte-order`, `--decode` and `--nodata none` (`nodata_tag` false) on
/// top of `read`, checked by the library.
fn terrain_read(
    mut read: ReadOptions,
    band: Option<&Bound<'_, PyAny>>,
    size: Option<&Bound<'_, PyAny>>,
    byte_order: Option<&str>,
    decode: Option<&str>,
    nodata_tag: bool,
) -> PyResult<ReadOptions> {
    read = read.with_nodata_tag(nodata_tag);
    if let Some(band) = band {
        let k = whole(band, "band")?;
        let k = u32::try_from(k).map_err(|_| {
            PyValueError::new_err(format!("invalid option: bands count from 1, as in GDAL: got band {k}"))
        })?;
        read = read.with_band(k);
    }
    let size = size.map(raw_size).transpose()?;
    let byte_order = byte_order.map(parse_named::<ByteOrder>).transpose()?;
    if let Some(raw) = RawOptions::given(size, byte_order) {
        read = read.with_raw(raw);
    }
    if let Some(packing) = decode {
        read = read.with_decode(parse_named::<PackedElevation>(packing)?);
    }
    read.validate().map_err(to_py_err)?;
    Ok(read)
}

/// `size=`: a `(width, height)` pair or the command line's `"WxH"`.
fn raw_size(size: &Bound<'_, PyAny>) -> PyResult<(usize, usize)> {
    if let Ok(text) = size.cast::<PyString>() {
        return normalfit::io::parse_size(&text.to_cow()?).map_err(to_py_err);
    }
    if let Ok(pair) = size.cast::<PyTuple>()
        && pair.len() == 2
    {
        let side = |i: usize, name: &str| -> PyResult<usize> {
            let v = whole(&pair.get_item(i)?, name)?;
            usize::try_from(v)
                .map_err(|_| PyValueError::new_err(format!("invalid option: RAW {name} must be at least 1, got {v}")))
        };
        return Ok((side(0, "width")?, side(1, "height")?));
    }
    Err(PyTypeError::new_err(format!("size must be a (width, height) pair or 'WxH', got {}", shown(size))))
}

/// `channel=`: a keyword (luma, r, g, b, a) or an OpenEXR channel's name,
/// as the library takes it (`Channel::named`, as `--channel` is); its
/// message names the keyword argument.
fn parse_channel(channel: Option<String>) -> PyResult<Option<Channel>> {
    channel.as_deref().map(Channel::named).transpose().map_err(|e| match e {
        Error::InvalidOption(m) => PyValueError::new_err(format!("invalid option: channel: {m}")),
        other => to_py_err(other),
    })
}

/// What a conversion did: `normalfit.convert`'s result.
#[pyclass(frozen, get_all, module = "normalfit")]
struct ConversionSummary {
    /// Columns.
    width: usize,
    /// Rows.
    height: usize,
    /// The format read (``"png"``, ``"exr"``, …).
    input_format: String,
    /// The border modes the fit used, ``(x, y)``, ``auto`` settled.
    borders: (&'static str, &'static str),
    /// Whether the rows streamed from decoder to encoder (else the image
    /// was read whole).
    streamed: bool,
    /// The tiling check, when the borders needed it and it ran.
    tiling: Option<Py<TilingReport>>,
    /// Warnings, one line each (a wrap that draws a seam, …).
    warnings: Vec<String>,
    /// The nodata value used (``nodata=``, else a GeoTIFF's GDAL_NODATA
    /// tag), or None: the map then has an alpha of validity.
    nodata: Option<f64>,
    /// Missing texels (alpha 0 in the map); 0 without a nodata value.
    missing: usize,
}

#[pymethods]
impl ConversionSummary {
    fn __repr__(&self) -> String {
        format!(
            "ConversionSummary(width={}, height={}, input_format='{}', borders=('{}', '{}'), streamed={}, warnings={:?})",
            self.width,
            self.height,
            self.input_format,
            self.borders.0,
            self.borders.1,
            py_bool(self.streamed),
            self.warnings
        )
    }
}

/// `convert` with every argument given (see `normalfit.convert`).
#[pyfunction]
#[allow(clippy::too_many_arguments)]
#[pyo3(signature = (src, dst, patch, fit, border, convention, scale, relief, invert, channel, bits, format, signed, compression, alpha, channels, residual, max_texels, layer, units, pixel_size, band, size, byte_order, decode, nodata, nodata_tag, detail=None, weights="uniform", product="normals", slope_units="degrees", zero_for_flat=false, azimuth=315.0, altitude=45.0))]
fn convert(
    py: Python<'_>,
    src: PathBuf,
    dst: PathBuf,
    patch: &Bound<'_, PyAny>,
    fit: &str,
    border: &Bound<'_, PyAny>,
    convention: &str,
    scale: Option<f64>,
    relief: Option<f64>,
    invert: bool,
    channel: Option<String>,
    bits: Option<u8>,
    format: Option<&str>,
    signed: bool,
    compression: &str,
    alpha: &str,
    channels: &str,
    residual: bool,
    max_texels: Option<&Bound<'_, PyAny>>,
    layer: Option<String>,
    units: &str,
    pixel_size: Option<(f64, f64)>,
    band: Option<&Bound<'_, PyAny>>,
    size: Option<&Bound<'_, PyAny>>,
    byte_order: Option<&str>,
    decode: Option<&str>,
    nodata: Option<f64>,
    nodata_tag: bool,
    detail: Option<&Bound<'_, PyAny>>,
    weights: &str,
    product: &str,
    slope_units: &str,
    zero_for_flat: bool,
    azimuth: f64,
    altitude: f64,
) -> PyResult<ConversionSummary> {
    let (opts, borders) = fit_options(patch, fit, border, convention, scale, relief, invert)?;
    let opts = with_weights(with_detail(opts, detail)?, weights)?.with_nodata(nodata);
    let map_units = map_units(units, pixel_size)?;
    let read = terrain_read(read_options(max_texels, layer)?, band, size, byte_order, decode, nodata_tag)?;
    let format = format.map(parse_named::<OutputFormat>).transpose()?;
    let compression = parse_named::<PngCompression>(compression)?;
    let layout = Layout::from_parts(parse_named(channels)?, parse_named(alpha)?).map_err(to_py_err)?;
    let mut conversion = Conversion::new()
        .with_fit(opts)
        .with_borders(borders)
        .with_read(read)
        .with_channel(parse_channel(channel)?)
        .with_format(format)
        .with_signed(signed)
        .with_compression(compression)
        .with_layout(layout)
        .with_residual(residual)
        .with_map_units(map_units)
        .with_product(parse_named::<Product>(product)?)
        .with_slope_units(parse_named::<SlopeUnits>(slope_units)?)
        .with_zero_for_flat(zero_for_flat)
        .with_sun(Sun::new(azimuth, altitude).map_err(to_py_err)?);
    conversion.bits = bits;
    let summary = py.detach(|| conversion.convert_file(&src, &dst)).map_err(|e| match e.place {
        Place::Input => file_error(&src, e.error, false),
        _ => file_error(&dst, e.error, true),
    })?;
    Ok(ConversionSummary {
        width: summary.width,
        height: summary.height,
        input_format: summary.input_format.to_string(),
        borders: (Border::name(summary.borders.x), Border::name(summary.borders.y)),
        streamed: summary.streamed,
        tiling: summary.tiling.map(|r| tiling_report_object(py, &r, summary.width, summary.height)).transpose()?,
        warnings: summary.warnings.iter().map(ToString::to_string).collect(),
        nodata: summary.nodata,
        missing: summary.missing,
    })
}

/// `decode_normals` with every argument given (see `normalfit.decode_normals`).
#[pyfunction]
#[pyo3(signature = (path, signed, max_texels, layer))]
fn decode_normals<'py>(
    py: Python<'py>,
    path: PathBuf,
    signed: bool,
    max_texels: Option<&Bound<'_, PyAny>>,
    layer: Option<String>,
) -> PyResult<Bound<'py, PyAny>> {
    let read = read_options(max_texels, layer)?;
    let (w, h, normals) =
        py.detach(|| normal_map::read(&path, &read, signed)).map_err(|e| file_error(&path, e, false))?;
    let flat: Vec<f32> = normals.into_flattened();
    Ok(PyArray1::from_vec(py, flat).reshape([h, w, 3])?.into_any())
}

/// `lit_view` with every argument given (see `normalfit.lit_view`).
#[pyfunction]
#[allow(clippy::too_many_arguments)]
#[pyo3(signature = (path, light, azimuth, altitude, tile, kind, channel, signed, patch, fit, border, convention, scale, relief, invert, max_texels, layer, units, pixel_size, band, size, byte_order, decode, nodata, nodata_tag, detail=None, weights="uniform"))]
fn lit_view<'py>(
    py: Python<'py>,
    path: PathBuf,
    light: Option<(f64, f64)>,
    azimuth: Option<f64>,
    altitude: Option<f64>,
    tile: bool,
    kind: &str,
    channel: Option<String>,
    signed: bool,
    patch: &Bound<'py, PyAny>,
    fit: &str,
    border: &Bound<'py, PyAny>,
    convention: &str,
    scale: Option<f64>,
    relief: Option<f64>,
    invert: bool,
    max_texels: Option<&Bound<'_, PyAny>>,
    layer: Option<String>,
    units: &str,
    pixel_size: Option<(f64, f64)>,
    band: Option<&Bound<'py, PyAny>>,
    size: Option<&Bound<'py, PyAny>>,
    byte_order: Option<&str>,
    decode: Option<&str>,
    nodata: Option<f64>,
    nodata_tag: bool,
    detail: Option<&Bound<'py, PyAny>>,
    weights: &str,
) -> PyResult<Bound<'py, PyAny>> {
    let light = light.map(|(azimuth, elevation)| Light::new(azimuth, elevation)).transpose().map_err(to_py_err)?;
    let (opts, borders) = fit_options(patch, fit, border, convention, scale, relief, invert)?;
    let opts = with_detail(opts, detail)?;
    let opts = with_weights(opts, weights)?;
    let lit = LitOptions::new()
        .with_fit(opts.with_nodata(nodata))
        .with_borders(borders)
        .with_lighting(light, azimuth, altitude)
        .map_err(to_py_err)?
        .with_tile(tile)
        .with_kind(parse_named(kind)?)
        .with_channel(parse_channel(channel)?)
        .with_signed(signed)
        .with_map_units(map_units(units, pixel_size)?);
    let read = terrain_read(read_options(max_texels, layer)?, band, size, byte_order, decode, nodata_tag)?;
    let view = py.detach(|| shade::lit_view_of_file(&path, &read, &lit)).map_err(|e| file_error(&path, e, false))?;
    let (w, h) = (view.width, view.height);
    Ok(PyArray1::from_vec(py, view.pixels).reshape([h, w])?.into_any())
}

/// `check_tiling` of a file (see `normalfit.check_tiling`).
#[pyfunction]
#[pyo3(signature = (path, threshold, kind, channel, max_texels, layer))]
fn check_tiling_file(
    py: Python<'_>,
    path: PathBuf,
    threshold: f64,
    kind: &str,
    channel: Option<String>,
    max_texels: Option<&Bound<'_, PyAny>>,
    layer: Option<String>,
) -> PyResult<TilingReport> {
    let opts = tiling_options(threshold, kind)?;
    let read = read_options(max_texels, layer)?;
    let channel = parse_channel(channel)?;
    let (raster, report) = py
        .detach(|| inspect::tiling_report_of_file(&path, &read, &opts, channel.as_ref()))
        .map_err(|e| file_error(&path, e, false))?;
    tiling_report_value(py, &report, raster.width, raster.height)
}

/// `height` of an array of normals of component type `T`, read as n by
/// the library's rule for their storage (encoded integers: 2c − 1).
fn height_typed<T: Element + Sample>(
    normals: &Bound<'_, PyUntypedArray>,
    holes: Option<&[bool]>,
    opts: &HeightOptions,
    stored: Storage,
    pool: Option<Borrowed>,
) -> PyResult<(Vec<f64>, usize, usize, normalfit::height::HeightReport)> {
    let py = normals.py();
    let shape = normals.shape();
    let (h, w) = (shape[0], shape[1]);
    if shape[2] != 3 {
        return Err(PyValueError::new_err(format!("normals must have shape (rows, columns, 3), got {shape:?}")));
    }
    let source = normals.cast::<PyArray3<T>>()?.try_readonly().map_err(|e| PyValueError::new_err(e.to_string()))?;
    let view = source.as_array();
    let pool = pool.as_ref().and_then(|b| b.pool.as_ref());
    py.detach(|| -> Result<_, Error> {
        let row = |y: usize, out: &mut [[f64; 3]]| {
            for (x, o) in out.iter_mut().enumerate() {
                *o = [0, 1, 2].map(|c| stored.normal(view[[y, x, c]]));
            }
        };
        let found = on_pool(pool, || heights_of_rows_with_holes(&row, w, h, holes, opts))?;
        Ok((found.values, w, h, found.report))
    })
    .map_err(to_py_err)
}

/// `height` with every argument given (see `normalfit.height`).
#[pyfunction]
#[allow(clippy::too_many_arguments)]
#[pyo3(signature = (normals, patch, fit, border, convention, scale, relief, invert, model, step, threads, holes))]
fn height<'py>(
    py: Python<'py>,
    normals: &Bound<'py, PyAny>,
    patch: &Bound<'py, PyAny>,
    fit: &str,
    border: &Bound<'py, PyAny>,
    convention: &str,
    scale: Option<f64>,
    relief: Option<f64>,
    invert: bool,
    model: &str,
    step: Option<f64>,
    threads: Option<&Bound<'py, PyAny>>,
    holes: Option<PyReadonlyArray2<'py, bool>>,
) -> PyResult<(Bound<'py, PyAny>, HeightInfo)> {
    let normals = as_array(normals, "normals", &[3])?;
    let shape = normals.shape();
    // The mask in row-major order, checked against the map's shape here:
    // the library takes a flat slice.
    let holes: Option<Vec<bool>> = match &holes {
        Some(mask) if mask.shape() != &shape[..2] => {
            return Err(PyValueError::new_err(format!(
                "holes must have the normals' shape ({}, {}), got {:?}",
                shape[0],
                shape[1],
                mask.shape()
            )));
        }
        Some(mask) => Some(mask.as_array().iter().copied().collect()),
        None => None,
    };
    let kind = sample_kind(normals, "normals")?;
    let opts = height_options(patch, fit, border, convention, scale, relief, invert, model)?;
    // Integers hold (n + 1)/2, as normals(dtype=...) and PNGs store it;
    // floats hold n itself, as normals() returns it.
    let stored = match kind {
        SampleKind::U8 => Storage::Int { bits: 8 },
        SampleKind::U16 => Storage::Int { bits: 16 },
        SampleKind::F32 => Storage::Float32 { signed: true },
        SampleKind::F64 => Storage::Float64 { signed: true },
    };
    let opts = opts.with_step(step.unwrap_or(stored.step()));
    opts.validate().map_err(to_py_err)?;
    let pool = pool(threads)?;
    let (values, w, h, report) = match kind {
        SampleKind::U8 => height_typed::<u8>(normals, holes.as_deref(), &opts, stored, pool),
        SampleKind::U16 => height_typed::<u16>(normals, holes.as_deref(), &opts, stored, pool),
        SampleKind::F32 => height_typed::<f32>(normals, holes.as_deref(), &opts, stored, pool),
        SampleKind::F64 => height_typed::<f64>(normals, holes.as_deref(), &opts, stored, pool),
    }?;
    let array = PyArray1::from_vec(py, values).reshape([h, w])?.into_any();
    Ok((array, HeightInfo::from_report(&report, Vec::new(), None, None)))
}

/// The height options from the keyword arguments, checked by the library.
#[allow(clippy::too_many_arguments)]
fn height_options(
    patch: &Bound<'_, PyAny>,
    fit: &str,
    border: &Bound<'_, PyAny>,
    convention: &str,
    scale: Option<f64>,
    relief: Option<f64>,
    invert: bool,
    model: &str,
) -> PyResult<HeightOptions> {
    let (opts, borders) = fit_options(patch, fit, border, "opengl", scale, relief, invert)?;
    let borders = borders.fixed().map_err(to_py_err)?;
    let opts = HeightOptions::from_fit(&opts.with_borders(borders))
        .with_convention(parse_named::<ConventionChoice>(convention)?)
        .with_model(parse_named::<Model>(model)?);
    opts.validate().map_err(to_py_err)?;
    Ok(opts)
}

/// What `height` and `height_file` found besides the heights.
#[pyclass(frozen, get_all, module = "normalfit")]
struct HeightInfo {
    /// The convention used (``"opengl"`` or ``"directx"``; chosen under auto).
    convention: &'static str,
    /// Under auto: the relative curl as OpenGL and as DirectX.
    curl: Option<(f64, f64)>,
    /// Texels with nz <= 0 or a non-finite component, taken as flat.
    bad_texels: usize,
    /// Solves run.
    iterations: usize,
    /// Whether the iteration met its tolerance.
    converged: bool,
    /// The RMS height error the input's quantisation leaves, if not exact.
    quantisation_error: Option<f64>,
    /// The smallest and largest height (NaNs left out).
    range: (f64, f64),
    /// Holes given, NaN in the heights.
    holes: usize,
    /// Texels no patch free of holes holds: NaN in the heights.
    undetermined: usize,
    /// A PNG output: the heights 0 and 1 stand for.
    png_range: Option<(f64, f64)>,
    /// A PNG output: the gain S·(hi − lo) with which `convert` of the PNG
    /// makes the normals again.
    png_scale: Option<f64>,
    /// Warnings, one line each.
    warnings: Vec<String>,
}

impl HeightInfo {
    fn from_report(
        r: &normalfit::height::HeightReport,
        warnings: Vec<String>,
        png_range: Option<(f64, f64)>,
        png_scale: Option<f64>,
    ) -> Self {
        HeightInfo {
            convention: r.convention.name(),
            curl: r.curl.map(|[a, b]| (a, b)),
            bad_texels: r.bad_texels,
            iterations: r.iterations,
            converged: r.converged,
            quantisation_error: r.quantisation_error,
            range: r.range,
            holes: r.holes,
            undetermined: r.undetermined,
            png_range,
            png_scale,
            warnings,
        }
    }
}

#[pymethods]
impl HeightInfo {
    fn __repr__(&self) -> String {
        format!(
            "HeightInfo(convention='{}', bad_texels={}, iterations={}, converged={}, range=({}, {}), warnings={:?})",
            self.convention,
            self.bad_texels,
            self.iterations,
            py_bool(self.converged),
            py_float(self.range.0),
            py_float(self.range.1),
            self.warnings
        )
    }
}

/// `height_file` with every argument given (see `normalfit.height_file`).
#[pyfunction]
#[allow(clippy::too_many_arguments)]
#[pyo3(signature = (src, dst, patch, fit, border, convention, scale, relief, invert, model, signed, format, max_texels, layer))]
fn height_file(
    py: Python<'_>,
    src: PathBuf,
    dst: PathBuf,
    patch: &Bound<'_, PyAny>,
    fit: &str,
    border: &Bound<'_, PyAny>,
    convention: &str,
    scale: Option<f64>,
    relief: Option<f64>,
    invert: bool,
    model: &str,
    signed: bool,
    format: Option<&str>,
    max_texels: Option<&Bound<'_, PyAny>>,
    layer: Option<String>,
) -> PyResult<HeightInfo> {
    let opts = height_options(patch, fit, border, convention, scale, relief, invert, model)?;
    let format = format.map(parse_named::<OutputFormat>).transpose()?;
    let conversion = HeightConversion::new()
        .with_options(opts)
        .with_read(read_options(max_texels, layer)?)
        .with_signed(signed)
        .with_format(format);
    let summary = py.detach(|| conversion.convert_file(&src, &dst)).map_err(|e| match e.place {
        Place::Input => file_error(&src, e.error, false),
        _ => file_error(&dst, e.error, true),
    })?;
    let warnings = summary.warnings.iter().map(ToString::to_string).collect();
    Ok(HeightInfo::from_report(&summary.report, warnings, summary.png_range, summary.png_scale))
}

/// An array of normals of component type `T` as f64 normals n, read by the
/// library's rule for their storage (integers: 2c − 1; floats: n).
fn normals_f64<T: Element + Sample>(
    array: &Bound<'_, PyUntypedArray>,
    what: &str,
    stored: Storage,
) -> PyResult<(Vec<[f64; 3]>, usize, usize)> {
    let shape = array.shape();
    if shape.len() != 3 || shape[2] != 3 {
        return Err(PyValueError::new_err(format!("{what} must have shape (rows, columns, 3), got {shape:?}")));
    }
    let (h, w) = (shape[0], shape[1]);
    let source = array.cast::<PyArray3<T>>()?.try_readonly().map_err(|e| PyValueError::new_err(e.to_string()))?;
    let view = source.as_array();
    let mut out = Vec::new();
    out.try_reserve_exact(w * h).map_err(|_| PyMemoryError::new_err(format!("cannot copy {what}")))?;
    for y in 0..h {
        for x in 0..w {
            out.push([0, 1, 2].map(|c| stored.normal(view[[y, x, c]])));
        }
    }
    Ok((out, w, h))
}

/// A normal array as f64 normals, whatever its sample type.
fn any_normals(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<(Vec<[f64; 3]>, usize, usize)> {
    let array = as_array(obj, what, &[3])?;
    match sample_kind(array, what)? {
        SampleKind::U8 => normals_f64::<u8>(array, what, Storage::Int { bits: 8 }),
        SampleKind::U16 => normals_f64::<u16>(array, what, Storage::Int { bits: 16 }),
        SampleKind::F32 => normals_f64::<f32>(array, what, Storage::Float32 { signed: true }),
        SampleKind::F64 => normals_f64::<f64>(array, what, Storage::Float64 { signed: true }),
    }
}

/// `blend` with every argument given (see `normalfit.blend`).
#[pyfunction]
#[pyo3(signature = (base, detail, method, strength, convention, detail_convention))]
fn blend<'py>(
    py: Python<'py>,
    base: &Bound<'py, PyAny>,
    detail: &Bound<'py, PyAny>,
    method: &str,
    strength: f64,
    convention: &str,
    detail_convention: Option<&str>,
) -> PyResult<Bound<'py, PyAny>> {
    let c = parse_named::<ConventionChoice>(convention)?;
    let dc = detail_convention.map(parse_named::<ConventionChoice>).transpose()?.unwrap_or(c);
    let opts = BlendOptions::new()
        .with_method(parse_named::<BlendMethod>(method)?)
        .with_strength(strength)
        .with_convention(c)
        .with_detail_convention(dc);
    opts.validate().map_err(to_py_err)?;
    let (b, bw, bh) = any_normals(base, "base")?;
    let (d, dw, dh) = any_normals(detail, "detail")?;
    let (out, _) =
        py.detach(|| normalfit::blend::blend::<f64, [f64; 3]>(&b, (bw, bh), &d, (dw, dh), &opts)).map_err(to_py_err)?;
    Ok(PyArray1::from_vec(py, out.into_flattened()).reshape([bh, bw, 3])?.into_any())
}

/// `check_map` with every argument given (see `normalfit.check_map`): the
/// report as the keys of `normalfit check --json`.
#[pyfunction]
#[allow(clippy::too_many_arguments)]
#[pyo3(signature = (path, convention, threshold, signed, fix, to, max_texels, layer))]
fn check_map<'py>(
    py: Python<'py>,
    path: PathBuf,
    convention: &str,
    threshold: Option<f64>,
    signed: bool,
    fix: Option<PathBuf>,
    to: Option<&str>,
    max_texels: Option<&Bound<'_, PyAny>>,
    layer: Option<String>,
) -> PyResult<Bound<'py, PyDict>> {
    let read = read_options(max_texels, layer)?;
    let mut tiling = TilingOptions::default();
    if let Some(t) = threshold {
        tiling = tiling.with_threshold(t);
    }
    tiling.validate().map_err(to_py_err)?;
    let opts = CheckOptions::new()
        .with_convention(parse_named::<ConventionChoice>(convention)?)
        .with_tiling(tiling)
        .with_signed(signed);
    let to = to.map(parse_named::<Convention>).transpose()?;
    if to.is_some() && fix.is_none() {
        return Err(PyValueError::new_err("to= needs fix= (the file the repaired map is written to)"));
    }
    let fix_opts = FixOptions::new().with_to(to);
    let report = py
        .detach(|| {
            let output = fix.as_deref().map(|p| (&fix_opts, normalfit::convert::Output::file(p)));
            check_and_fix(normalfit::convert::Input::Path(&path), &read, &opts, output)
        })
        .map_err(|e| match (e.place, &fix) {
            (Place::Output, Some(out)) => file_error(out, e.error, true),
            _ => file_error(&path, e.error, false),
        })?;
    check_dict(py, &path, &report)
}

/// The report as a dict with the keys of `normalfit check --json`.
fn check_dict<'py>(py: Python<'py>, path: &Path, r: &CheckReport) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    let g = &r.guess;
    d.set_item("path", path.display().to_string())?;
    d.set_item("width", r.width)?;
    d.set_item("height", r.height)?;
    let storage = match r.sample {
        normalfit::io::SampleType::Int { bits } | normalfit::io::SampleType::SignedInt { bits } => {
            format!("{bits}-bit")
        }
        _ => "float".into(),
    };
    d.set_item("storage", storage)?;
    d.set_item("layout", if r.layout == MapLayout::Rg { "rg" } else { "rgb" })?;
    let length = PyDict::new(py);
    length.set_item("tolerance", r.length_tolerance)?;
    length.set_item("off", r.off_length)?;
    length.set_item("share", r.share(r.off_length))?;
    d.set_item("length", length)?;
    let negative = PyDict::new(py);
    negative.set_item("count", r.negative_z)?;
    negative.set_item("share", r.share(r.negative_z))?;
    d.set_item("negative_z", negative)?;
    d.set_item("convention", g.convention.name())?;
    d.set_item("confident", g.confident)?;
    d.set_item("confidence", g.confidence)?;
    let curl = PyDict::new(py);
    curl.set_item("opengl", g.curl[0])?;
    curl.set_item("directx", g.curl[1])?;
    curl.set_item("scale", g.scale)?;
    d.set_item("curl", curl)?;
    match r.banding {
        Some(b) => {
            let banding = PyDict::new(py);
            banding.set_item("score", b.score)?;
            banding.set_item("windows", b.windows)?;
            banding.set_item("banded", b.banded)?;
            d.set_item("banding", banding)?;
        }
        None => d.set_item("banding", py.None())?,
    }
    let tiling = PyDict::new(py);
    for (axis, a) in [("x", r.tiling.x), ("y", r.tiling.y)] {
        let ad = PyDict::new(py);
        ad.set_item("score", a.score)?;
        ad.set_item("seamless", a.seamless)?;
        tiling.set_item(axis, ad)?;
    }
    tiling.set_item("seamless", r.tiling.seamless())?;
    d.set_item("tiling", tiling)?;
    let findings: Vec<&str> = r.findings().iter().map(|f| f.name()).collect();
    d.set_item("findings", findings)?;
    d.set_item("clean", r.clean())?;
    Ok(d)
}

/// The native half of the `normalfit` package.
#[pymodule]
fn _normalfit(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(normals, m)?)?;
    m.add_function(wrap_pyfunction!(mips, m)?)?;
    m.add_function(wrap_pyfunction!(curvature, m)?)?;
    m.add_function(wrap_pyfunction!(_kept_pools, m)?)?;
    m.add_function(wrap_pyfunction!(window_normals, m)?)?;
    m.add_function(wrap_pyfunction!(window_plan, m)?)?;
    m.add_function(wrap_pyfunction!(window_halo, m)?)?;
    m.add_function(wrap_pyfunction!(border_names, m)?)?;
    m.add_function(wrap_pyfunction!(geotransform_spacing, m)?)?;
    m.add_function(wrap_pyfunction!(centres_geotransform, m)?)?;
    m.add_function(wrap_pyfunction!(check_tiling, m)?)?;
    m.add_function(wrap_pyfunction!(check_tiling_file, m)?)?;
    m.add_function(wrap_pyfunction!(convert, m)?)?;
    m.add_function(wrap_pyfunction!(decode_normals, m)?)?;
    m.add_function(wrap_pyfunction!(lit_view, m)?)?;
    m.add_function(wrap_pyfunction!(height, m)?)?;
    m.add_function(wrap_pyfunction!(height_file, m)?)?;
    m.add_function(wrap_pyfunction!(blend, m)?)?;
    m.add_function(wrap_pyfunction!(check_map, m)?)?;
    m.add_class::<HeightInfo>()?;
    m.add_class::<ConversionSummary>()?;
    m.add_class::<AxisReport>()?;
    m.add_class::<TilingReport>()?;
    m.add_class::<PyHeightSeams>()?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
