//! Slope, aspect and hillshade of heights held in memory (docs/products.md):
//! what `convert --product slope|aspect|hillshade` writes, for a caller
//! holding the heights (the Python package's `normalfit.slope` and
//! `normalfit.xarray`), the whole image or a window of it (a Dask chunk).
//!
//! The fit is [`FitRequest`]'s, the value of each texel made in the fit's
//! loop by the engine's own per-texel functions: the texel
//! `Measure::with_texel` chooses (a slope or an aspect), and the GIS sun's
//! grey (`light::Grey`), as the slope or aspect map's and the lit view's
//! stages, streamed or whole, make them. So the values are the command
//! line's on the same heights and options, bit for bit.

use crate::error::Result;
use crate::fit::{FitRequest, Heights};
use crate::io::Affine;
use crate::light::{Grey, Sun};
use crate::options::Convention;
use crate::units::{Measure, MeasureTexel, WithTexel};

/// The slope or aspect map ([`Measure`]) of `heights` (`width` ×
/// `height`, row-major, any [`Heights`]), fitted as `request` says (the
/// whole image, or its [`window`](FitRequest::window)) into `out` (as
/// many texels as the normals `request` makes), on a raster placed on
/// the map by `affine` (its GDAL geotransform; `None`: north-up, row 0
/// north), the aspect the map's whichever way its rows run; `hole` at missing texels
/// (the command line's [`crate::units::NODATA`], or NaN). Holes are
/// texels of the options' nodata value and non-finite heights (as
/// [`FitRequest::holes`] says); a texel whose patch has fewer than three
/// valid points, or collinear ones, is missing too. Returns the count of
/// missing texels.
///
/// ```
/// use normalfit::{FitRequest, Options, SlopeUnits};
/// use normalfit::products::measure_into;
/// use normalfit::units::Measure;
/// // A plane rising 1 in 10 to the east, 1-metre texels: 5.7106°.
/// let (w, h) = (6, 5);
/// let heights: Vec<f64> = (0..w * h).map(|k| 0.1 * (k % w) as f64).collect();
/// let opts = Options::new().with_fit(normalfit::Fit::Vertical).with_borders(normalfit::Borders::both(normalfit::Border::Clamp));
/// let mut slope = vec![0.0f32; w * h];
/// let missing = measure_into(FitRequest::new(&opts), Measure::Slope(SlopeUnits::Degrees), None, f32::NAN, &heights, w, h, &mut slope)?;
/// assert_eq!(missing, 0);
/// assert!((slope[2 * w + 3] - 5.710_593).abs() < 1e-5);
/// # Ok::<(), normalfit::Error>(())
/// ```
///
/// Errors: those of [`FitRequest::normals_into`]; [`crate::Error::Limits`]
/// when the memory of a band's texels (4 bytes a texel) is not there.
#[allow(clippy::too_many_arguments)] // the heights and output as `normals_into`'s, and what the map needs
pub fn measure_into<S: Heights + ?Sized>(
    request: FitRequest<'_>,
    measure: Measure,
    affine: Option<&Affine>,
    hole: f32,
    heights: &S,
    width: usize,
    height: usize,
    out: &mut [f32],
) -> Result<usize> {
    check_output(out.len(), request.output_size(width, height))?;
    measure.with_texel(MeasureBands { request, affine, hole, heights, size: (width, height), out })
}

/// [`measure_into`]'s bands, in the texel the measure's fit makes
/// ([`Measure::with_texel`]).
struct MeasureBands<'a, S: ?Sized> {
    request: FitRequest<'a>,
    affine: Option<&'a Affine>,
    hole: f32,
    heights: &'a S,
    size: (usize, usize),
    out: &'a mut [f32],
}

impl<S: Heights + ?Sized> WithTexel for MeasureBands<'_, S> {
    type Output = Result<usize>;

    fn run<T: MeasureTexel>(self) -> Result<usize> {
        let MeasureBands { request, affine, hole, heights, size, out } = self;
        let row = request.output_width(size.0);
        // Each band's values from its texels, which are then dropped: the
        // texels are never held for the whole image.
        let mut band = |first: usize, texels: &[T], valid: Option<&[bool]>| {
            let Some(out) = out.get_mut(first * row..first * row + texels.len()) else { return };
            out.iter_mut().zip(texels).for_each(|(o, t)| *o = t.value());
            if let Some(valid) = valid {
                out.iter_mut().zip(valid).filter(|(_, v)| !**v).for_each(|(o, _)| *o = hole);
            }
        };
        request.on_map(affine).normals_in_bands(heights, size, &mut band)
    }
}

/// The hillshade of `heights` under `sun`, as `convert --product
/// hillshade` and `gdaldem hillshade` draw it: one byte a texel, 1 + 254 ·
/// max(0, n · L) rounded (1 full shadow), 0 at missing texels (gdaldem's
/// nodata). The sun's azimuth is the map's on a raster placed by
/// `affine` (`None`: north-up). `request`, `heights` and the holes as for
/// [`measure_into`]; `out` one
/// byte a texel. Returns the count of missing texels.
///
/// Errors: those of [`FitRequest::normals_into`]; [`crate::Error::Limits`]
/// when the memory of a band's greys (1 byte a texel) is not there.
pub fn hillshade_into<S: Heights + ?Sized>(
    request: FitRequest<'_>,
    sun: Sun,
    affine: Option<&Affine>,
    heights: &S,
    width: usize,
    height: usize,
    out: &mut [u8],
) -> Result<usize> {
    let convention: Convention = request.convention();
    let lamp = crate::light::Lamp::sun(sun, affine, convention);
    let (texels, row) = (out.len(), request.output_width(width));
    let mut band = |first: usize, greys: &[Grey<true>], valid: Option<&[bool]>| {
        let Some(out) = out.get_mut(first * row..first * row + greys.len()) else { return };
        out.iter_mut().zip(greys).for_each(|(o, g)| *o = g.0);
        if let Some(valid) = valid {
            out.iter_mut().zip(valid).filter(|(_, v)| !**v).for_each(|(o, _)| *o = 0);
        }
    };
    check_output(texels, request.output_size(width, height))?;
    request.lit(lamp).normals_in_bands(heights, (width, height), &mut band)
}

/// An output of `texels` for a request making `size` texels.
fn check_output(texels: usize, (width, height): (usize, usize)) -> Result<()> {
    let expected = crate::fit::checked_len(width, height)?;
    if texels != expected {
        return Err(crate::Error::BufferSize { expected, actual: texels });
    }
    Ok(())
}
