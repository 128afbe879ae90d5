//! A normal map file to a height map file in one call, as `normalfit
//! height` does: the normals read back from the file's R, G and B (c =
//! (n + 1)/2, or n for a signed float map), the step of their storage
//! taken for the quantisation (both [`Storage`]'s rule), the heights written as an EXR of float
//! heights (channel Y, mean 0, units of the gain) or a 16-bit gray PNG
//! normalised to [0, 1] with the range in the summary. Outputs appear
//! whole or not at all and never replace the input. Nothing prints:
//! warnings are data ([`HeightWarning`]).
//!
//! Holes ([`Holes`]): by default those normalfit's `convert` writes, an
//! alpha of validity's 0s (an alpha holding nothing but 0 and full) and
//! normals with a component not finite; or a mask file's. They come back
//! NaN in an EXR or float TIFF (its GDAL_NODATA tag "nan"), and alpha 0 in
//! a PNG, which then is gray and alpha.
//!
//! ```no_run
//! use normalfit::height::file::HeightConversion;
//! use normalfit::height::{ConventionChoice, HeightOptions};
//!
//! let conversion = HeightConversion::new()
//!     .with_options(HeightOptions::new().with_convention(ConventionChoice::Auto));
//! let summary = conversion.convert_file("rock_normal.png".as_ref(), "rock_height.exr".as_ref())?;
//! println!("{:?} {:?}", summary.report.convention, summary.warnings);
//! # Ok::<(), normalfit::convert::ConvertError>(())
//! ```

use std::fmt;
use std::path::{Path, PathBuf};

use crate::engine::{self, ConvertError, Input, Output, Place};
use crate::error::{Error, Result};
use crate::io::{self, ExrDepth, InputFormat, OutputFormat, PngDepth, PngOptions, ReadOptions, SampleType};
use crate::normal_map::{Storage, normal_component};
use crate::par::prelude::*;
use crate::samples::{Sample, Samples, contract, try_vec, with_slice};

use super::{HeightOptions, HeightReport, SlopeField, heights_of_slopes, heights_of_slopes_with_holes, row_slopes};

/// Which texels of a normal map are holes (heights not asked for).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
#[non_exhaustive]
pub enum Holes {
    /// The holes normalfit's `convert` writes: where an alpha channel
    /// holding only 0 and full (an alpha of validity, not of heights) is 0,
    /// and where a normal's component is not finite (a float map's NaN).
    /// The default.
    #[default]
    Auto,
    /// None: every texel's normal is read (one without a slope is flat).
    None,
    /// The texels a mask image marks: where its alpha is 0 if it has one,
    /// else where its first channel (gray, or red) is not 0; and, as under
    /// auto, normals with a component not finite. Same size as the map.
    File(PathBuf),
}

/// Something the caller may want to tell its user; the heights were written.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub enum HeightWarning {
    /// Texels with nz ≤ 0 or a non-finite component, taken as flat.
    BadTexels(usize),
    /// The normals are stored in 8 bits: the RMS height error their
    /// rounding leaves (height units), and that as a fraction of the range.
    Precision {
        /// Bits per stored component.
        bits: u8,
        /// RMS height error from the rounding.
        error: f64,
        /// `error` over the heights' range.
        relative: f64,
    },
    /// The iteration (orthogonal fit, clamp with N ≥ 5) stopped before its
    /// tolerance: the best heights found were written.
    NotConverged {
        /// Solves run.
        iterations: usize,
    },
    /// Texels that are not holes but that every patch holding them holds
    /// a hole: no equation sees them, and they were written as holes.
    Undetermined(usize),
}

impl fmt::Display for HeightWarning {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            HeightWarning::BadTexels(n) => {
                write!(f, "{n} texels have nz ≤ 0 or a non-finite component: taken as flat")
            }
            HeightWarning::Precision { bits, error, relative } => write!(
                f,
                "{bits}-bit normals lose precision: their rounding leaves an RMS height error of {error:.3e} ({:.3} % of the range); a 16-bit or float normal map keeps it",
                relative * 100.0
            ),
            HeightWarning::NotConverged { iterations } => {
                write!(f, "the iteration did not settle in {iterations} solves: the best heights found were written")
            }
            HeightWarning::Undetermined(n) => {
                write!(f, "{n} texels lie in no patch free of holes: undetermined, written as holes")
            }
        }
    }
}

impl std::str::FromStr for Holes {
    type Err = Error;

    /// `auto`, `none`, or a mask's path (`./auto` for a file named so).
    fn from_str(s: &str) -> Result<Holes> {
        match s {
            "auto" => Ok(Holes::Auto),
            "none" => Ok(Holes::None),
            "" => Err(Error::InvalidOption("holes: auto, none or a mask file, not an empty name".into())),
            path => Ok(Holes::File(PathBuf::from(path))),
        }
    }
}

/// What a conversion did.
#[derive(Clone, Debug)]
#[non_exhaustive]
pub struct HeightSummary {
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// The format read.
    pub input_format: InputFormat,
    /// The normal map's samples.
    pub sample: SampleType,
    /// The format written.
    pub format: OutputFormat,
    /// The solve's report (convention chosen, range, …).
    pub report: HeightReport,
    /// For a PNG: the heights that 0 and 1 stand for. `convert -s S·(hi −
    /// lo)` of the PNG makes the normals again.
    pub png_range: Option<(f64, f64)>,
    /// For a PNG: that gain, S·(hi − lo) with S the gain for this width.
    pub png_scale: Option<f64>,
    /// The warnings, in order.
    pub warnings: Vec<HeightWarning>,
}

/// Every choice of a normal-map-to-height conversion.
#[derive(Clone, Debug, Default)]
#[non_exhaustive]
pub struct HeightConversion {
    /// The solve's options; [`HeightOptions::step`] is replaced by the
    /// file's storage step unless [`HeightConversion::step`] is set.
    pub options: HeightOptions,
    /// Limits and the EXR layer.
    pub read: ReadOptions,
    /// Float maps hold n itself, not (n + 1)/2.
    pub signed: bool,
    /// The output format when the output's name does not say (default EXR).
    pub format: Option<OutputFormat>,
    /// The step of a stored component, if not the file's.
    pub step: Option<f64>,
    /// Which texels are holes. Default: [`Holes::Auto`].
    pub holes: Holes,
}

impl HeightConversion {
    /// The defaults.
    #[must_use]
    pub fn new() -> Self {
        HeightConversion::default()
    }
    /// With these solve options.
    #[must_use]
    pub fn with_options(mut self, options: HeightOptions) -> Self {
        self.options = options;
        self
    }
    /// With these read options.
    #[must_use]
    pub fn with_read(mut self, read: ReadOptions) -> Self {
        self.read = read;
        self
    }
    /// Float maps hold n itself.
    #[must_use]
    pub fn with_signed(mut self, signed: bool) -> Self {
        self.signed = signed;
        self
    }
    /// The format when the name does not say.
    #[must_use]
    pub fn with_format(mut self, format: Option<OutputFormat>) -> Self {
        self.format = format;
        self
    }
    /// With these holes.
    #[must_use]
    pub fn with_holes(mut self, holes: Holes) -> Self {
        self.holes = holes;
        self
    }

    /// The holes of a decoded normal map (`None`: none), as
    /// [`HeightConversion::holes`] says; a mask file is read here.
    ///
    /// Errors: a mask file that cannot be read, or whose size is not the
    /// map's (the message names the file).
    fn hole_mask(&self, raster: &io::Raster, planes: [&Samples; 3]) -> Result<Option<Vec<bool>>> {
        let (w, h) = (raster.width, raster.height);
        let len = w * h;
        let mut mask = match &self.holes {
            Holes::None => return Ok(None),
            Holes::Auto => {
                let validity = raster
                    .plane("A")
                    .map(|a| &a.data)
                    .filter(|a| (0..a.len()).all(|i| a.height(i).is_some_and(|v| v == 0.0 || v == 1.0)));
                match validity {
                    Some(alpha) => (0..len).map(|i| alpha.height(i) == Some(0.0)).collect(),
                    None => vec![false; len],
                }
            }
            Holes::File(path) => {
                let named = |problem: String| Error::InvalidOption(format!("holes mask {}: {problem}", path.display()));
                let mask = engine::decode_whole(Input::Path(path), &self.read).map_err(|e| named(e.to_string()))?;
                if (mask.width, mask.height) != (w, h) {
                    return Err(named(format!(
                        "{} × {} texels, the normal map {w} × {h}: a mask is the map's size",
                        mask.width, mask.height
                    )));
                }
                match (mask.plane("A"), mask.planes.first()) {
                    (Some(alpha), _) => (0..len).map(|i| alpha.data.height(i) == Some(0.0)).collect(),
                    (None, Some(first)) => (0..len).map(|i| first.data.height(i).is_none_or(|v| v != 0.0)).collect(),
                    (None, None) => return Err(named("no channel".into())),
                }
            }
        };
        // Texels whose normal is not a number are holes too: rows in
        // parallel, each plane read in its own type.
        let rows_with_holes = mask
            .par_chunks_mut(w.max(1))
            .enumerate()
            .map(|(y, row)| {
                for plane in planes {
                    with_slice!(plane, s => {
                        for (m, &v) in row.iter_mut().zip(s.get(y * w..).unwrap_or_default()) {
                            *m |= !contract(v).is_finite();
                        }
                    });
                }
                row.iter().any(|&m| m)
            })
            .filter(|&any| any)
            .count();
        Ok((rows_with_holes > 0).then_some(mask))
    }

    /// Reads the normal map `input` and writes its heights to `output`.
    ///
    /// Errors: [`Place::Input`] for reading, decoding, a map without R, G
    /// and B, invalid options and the solve; [`Place::Output`] for the
    /// output's name, memory, encoding and writing, and an output that is
    /// the input.
    pub fn convert_file(&self, input: &Path, output: &Path) -> Result<HeightSummary, ConvertError> {
        self.convert(Input::Path(input), Output::file(output))
    }

    /// The output format for a file at `path` (`None`: a writer): its
    /// extension's, else [`HeightConversion::format`], else EXR.
    ///
    /// Errors: an extension that names no format written.
    pub fn output_format(&self, path: Option<&Path>) -> Result<OutputFormat> {
        let named = path.map(OutputFormat::from_path).transpose()?.flatten();
        Ok(named.or(self.format).unwrap_or(OutputFormat::Exr))
    }

    /// Reads the normal map `input` (a file, or an encoded image in
    /// memory: standard input) and writes its heights to `output` (a file,
    /// written atomically and never over the input, its folder made if
    /// asked; or any writer, given the whole encoded image at once, so a
    /// failure writes nothing).
    ///
    /// Errors: as [`HeightConversion::convert_file`].
    pub fn convert(&self, input: Input<'_>, output: Output<'_>) -> Result<HeightSummary, ConvertError> {
        let fail_in = |error| ConvertError { place: Place::Input, error };
        let fail_out = |error| ConvertError { place: Place::Output, error };
        let path = match &output {
            Output::File { path, .. } => Some(*path),
            _ => None,
        };
        let format = self.output_format(path).map_err(fail_out)?;
        self.options.validate().map_err(fail_in)?;
        if let (Input::Path(input), Output::File { path, .. }) = (&input, &output)
            && crate::io::same_file(input, path)
        {
            return Err(fail_out(Error::InvalidOption(
                "the output is the input (or a link to it): normalfit never writes over an input".into(),
            )));
        }
        // The inverse needs the whole image: decoded whole by the engine's
        // source, with the same reading and errors as every command.
        let mut raster = engine::decode_whole(input, &self.read).map_err(fail_in)?;
        let (w, h) = (raster.width, raster.height);
        let (input_format, sample) = (raster.format.clone(), raster.sample);
        if ["R", "G", "B"].iter().any(|&name| raster.plane(name).is_none()) {
            return Err(fail_in(Error::Unsupported("a normal map needs R, G and B channels".into())));
        }
        let stored = Storage::of_file(raster.sample, self.signed).map_err(fail_in)?;
        let bits = match stored {
            Storage::Int { bits } => Some(bits),
            _ => None,
        };
        let options = HeightOptions { step: self.step.unwrap_or(stored.step()), ..self.options.clone() };
        let holes = {
            let rgb = ["R", "G", "B"].map(|name| raster.plane(name).map(|p| &p.data));
            let [Some(r), Some(g), Some(b)] = rgb else { unreachable!("checked above") };
            self.hole_mask(&raster, [r, g, b]).map_err(fail_in)?
        };
        match &holes {
            Some(_) => super::check_masked(w, h, &options),
            None => super::memory::check(w, h, &options),
        }
        .map_err(fail_in)?;
        // The normals stay for the solve, which makes the slopes from them
        // row by row at each pass: R, G and B only.
        raster.planes.retain(|p| ["R", "G", "B"].contains(&p.name.as_str()));
        let planes = ["R", "G", "B"].map(|name| raster.plane(name).map(|p| &p.data));
        let [Some(r), Some(g), Some(b)] = planes else { unreachable!("checked above") };
        let planes = [r, g, b];
        let rows = |y: usize, sx: &mut [f64], sy: &mut [f64], holes: Option<&[bool]>| {
            let at = y * w..(y + 1) * w;
            match planes {
                [Samples::U8(r), Samples::U8(g), Samples::U8(b)] => stored_slopes(stored, [r, g, b], at, holes, sx, sy),
                [Samples::U16(r), Samples::U16(g), Samples::U16(b)] => {
                    stored_slopes(stored, [r, g, b], at, holes, sx, sy)
                }
                [Samples::F32(r), Samples::F32(g), Samples::F32(b)] => {
                    stored_slopes(stored, [r, g, b], at, holes, sx, sy)
                }
                [Samples::F64(r), Samples::F64(g), Samples::F64(b)] => {
                    stored_slopes(stored, [r, g, b], at, holes, sx, sy)
                }
                // Planes of several types (no reader makes them): a sample
                // at a time.
                _ => row_slopes(
                    |x| planes.map(|p| p.height(at.start + x).map_or(f64::NAN, |c| stored.normal(c))),
                    holes,
                    sx,
                    sy,
                ),
            }
        };
        let field = SlopeField::of_planes(&rows, w, h, holes.as_deref()).map_err(fail_in)?;
        let found = match &holes {
            Some(holes) => heights_of_slopes_with_holes(&field, holes, &options),
            None => heights_of_slopes(&field, &options),
        }
        .map_err(fail_in)?;
        // The normals go before the output is made.
        drop(raster);
        let report = found.report.clone();
        let (lo, hi) = report.range;
        let png_range = (format == OutputFormat::Png).then_some((lo, hi));
        let png_scale = png_range.map(|(lo, hi)| options.scale_for_width(w) * (hi - lo));
        let values = found.values;
        // Float files hold the heights as f32: beyond its range they would
        // be written infinite.
        let f32_max = f64::from(f32::MAX);
        if format != OutputFormat::Png && (lo < -f32_max || hi > f32_max) {
            let reach = if hi > f32_max { hi } else { lo };
            return Err(fail_out(Error::InvalidOption(format!(
                "heights reach {reach:.3e}, beyond the ±3.4e38 of the 32-bit floats {format} files hold here: give a larger scale"
            ))));
        }
        if let Output::File { path, create_folder: true } = output
            && let Some(parent) = path.parent()
            && !parent.as_os_str().is_empty()
        {
            std::fs::create_dir_all(parent).map_err(|e| {
                fail_out(Error::Io(std::io::Error::new(e.kind(), format!("cannot create the output folder: {e}"))))
            })?;
        }
        let mut files = io::FileSet::new(io::Replace::Always);
        let result = match format {
            // Converted to f32 as the blocks are written: no copy of the
            // heights (67 MB at 4096²).
            OutputFormat::Exr => crate::engine::write_to(output, &mut files, |file| {
                io::exr::write::write_exr_rows(file, w, h, ExrDepth::Float, &["Y"], |push| {
                    let mut stored = Vec::with_capacity(w.saturating_mul(EXR_ROWS));
                    values.chunks(w.saturating_mul(EXR_ROWS)).try_for_each(|rows| {
                        stored.clear();
                        stored.par_extend(rows.par_iter().map(|&v| v as f32));
                        push(&stored)
                    })
                })
            }),
            // Float heights, as in the EXR, a float32 one-band TIFF.
            #[cfg(feature = "tiff")]
            OutputFormat::Tiff => crate::engine::write_to(output, &mut files, |file| {
                // NaN at holes, which GDAL reads as nodata by the tag.
                let nodata = holes.is_some().then_some(f64::NAN);
                let tags = io::encoding::TiffTags { nodata, ..io::encoding::TiffTags::default() };
                io::tiff::write::write_tiff_rows(file, (w, h), 1, tags, |push| {
                    let mut stored = Vec::with_capacity(w.saturating_mul(EXR_ROWS));
                    values.chunks(w.saturating_mul(EXR_ROWS)).try_for_each(|rows| {
                        stored.clear();
                        stored.par_extend(rows.par_iter().map(|&v| v as f32));
                        push(&stored)
                    })
                })
            }),
            #[cfg(not(feature = "tiff"))]
            OutputFormat::Tiff => Err(io::write::no_tiff()),
            OutputFormat::Dds | OutputFormat::Ktx2 => {
                Err(Error::Unsupported("heights are written as .exr, .tif or .png, not as a GPU texture".into()))
            }
            OutputFormat::Png if holes.is_some() => {
                // Gray and alpha: alpha 0 where the height is NaN.
                let span = hi - lo;
                let unit = if span > 0.0 { 65535.0 / span } else { 0.0 };
                let mut stored: Vec<u16> = try_vec(values.len().saturating_mul(2)).map_err(fail_out)?;
                stored.extend(values.iter().flat_map(|&v| {
                    if v.is_nan() { [0, 0] } else { [((v - lo) * unit).round().clamp(0.0, 65535.0) as u16, 65535] }
                }));
                drop(values);
                crate::engine::write_to(output, &mut files, |file| {
                    io::png::write::png_gray_alpha16(
                        &stored,
                        (w, h),
                        PngOptions::new(PngDepth::Sixteen).compression,
                        file,
                    )
                })
            }
            OutputFormat::Png => {
                let span = hi - lo;
                let mut stored: Vec<u16> = try_vec(values.len()).map_err(fail_out)?;
                let unit = if span > 0.0 { 65535.0 / span } else { 0.0 };
                stored.extend(values.iter().map(|&v| ((v - lo) * unit).round().clamp(0.0, 65535.0) as u16));
                drop(values);
                crate::engine::write_to(output, &mut files, |file| {
                    io::encode_gray(&stored, w, h, &PngOptions::new(PngDepth::Sixteen).into(), file)
                })
            }
        };
        result.and_then(|()| files.commit()).map_err(fail_out)?;
        let mut warnings = Vec::new();
        if report.bad_texels > 0 {
            warnings.push(HeightWarning::BadTexels(report.bad_texels));
        }
        if let (Some(bits @ ..=8), Some(error)) = (bits, report.quantisation_error) {
            let span = hi - lo;
            warnings.push(HeightWarning::Precision {
                bits,
                error,
                relative: if span > 0.0 { error / span } else { 0.0 },
            });
        }
        if report.undetermined > 0 {
            warnings.push(HeightWarning::Undetermined(report.undetermined));
        }
        if !report.converged {
            warnings.push(HeightWarning::NotConverged { iterations: report.iterations });
        }
        Ok(HeightSummary { width: w, height: h, input_format, sample, format, report, png_range, png_scale, warnings })
    }
}

/// Row `at`'s slopes of the normals stored in three planes of one sample
/// type: read, made normals and divided in one loop, compiled for each
/// type on its own and for the widest vectors the processor has
/// ([`pulp::Arch`]; the same bits in every instruction set: nothing fuses
/// a multiply with an add).
#[inline(never)]
fn stored_slopes<T: Sample>(
    stored: Storage,
    [r, g, b]: [&[T]; 3],
    at: std::ops::Range<usize>,
    holes: Option<&[bool]>,
    sx: &mut [f64],
    sy: &mut [f64],
) -> usize {
    let (r, g, b) = (&r[at.clone()], &g[at.clone()], &b[at]);
    pulp::Arch::new().dispatch(StoredSlopes { signed: stored.is_signed(), rgb: [r, g, b], holes, sx, sy })
}

/// [`stored_slopes`]'s arguments, for [`pulp::Arch::dispatch`].
struct StoredSlopes<'a, T> {
    signed: bool,
    rgb: [&'a [T]; 3],
    holes: Option<&'a [bool]>,
    sx: &'a mut [f64],
    sy: &'a mut [f64],
}

impl<T: Sample> pulp::WithSimd for StoredSlopes<'_, T> {
    type Output = usize;

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _simd: S) -> usize {
        let StoredSlopes { signed, rgb: [r, g, b], holes, sx, sy } = self;
        let w = r.len();
        let (g, b, sx) = (&g[..w], &b[..w], &mut sx[..w]);
        // One loop for each choice of the component's rule.
        if signed {
            let n = |x: usize| [r[x], g[x], b[x]].map(|v| normal_component(v, true));
            row_slopes(n, holes, sx, sy)
        } else {
            let n = |x: usize| [r[x], g[x], b[x]].map(|v| normal_component(v, false));
            row_slopes(n, holes, sx, sy)
        }
    }
}

/// Rows of heights converted to f32 at a time for an EXR.
const EXR_ROWS: usize = 1024;
