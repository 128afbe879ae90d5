//! Rows of a height map read one at a time: the one trait every streamed
//! reader implements ([`RowSource`]: PNG, scan-line EXR, TIFF bands), and
//! the rows of a fit in map units (`StoredRows`). The streaming pipeline
//! ([`crate::pipeline`]) fits them band by band.

use crate::error::Result;
use crate::samples::try_vec;

/// The rows of a height map, top to bottom, decoded as they are asked for.
///
/// Rows are `f64` values, each the stored sample (an 8- or 16-bit
/// integer, or a float) or a height computed from several (luma): `f64`
/// holds them all exactly, and the height of a value v is
/// v · [`unit`](Self::unit). Integers are not divided before the fit,
/// which folds the unit into its gain, as it does for the same samples
/// decoded whole ([`crate::samples`]), and so gives the same bits.
pub trait RowSource: Send {
    /// Columns.
    fn width(&self) -> usize;

    /// Rows.
    fn height(&self) -> usize;

    /// The height of a row value of 1: 1 / (2^bits − 1) for integer
    /// samples as stored, 1 for floats and heights.
    fn unit(&self) -> f64;

    /// The row value of a stored sample value `v` (a nodata value as a
    /// file's tag or the user gives it): `v` itself, unless the source
    /// divides its samples (a TIFF's signed and 32-bit integers, given in
    /// contract units), and then `v` divided the same way.
    fn row_value(&self, v: f64) -> f64 {
        v
    }

    /// The stored value of a row value of 1, and whether stored values
    /// are whole numbers that the division rounded: `(1, false)` for rows
    /// of the values as stored (a picked channel's integers, floats);
    /// `(2^bits − 1, false)` for luma, made in contract units; `(2^bits −
    /// 1, true)` for a TIFF's signed and 32-bit integers, which come
    /// divided. A fit in map units takes the stored values
    /// (`StoredRows`), as [`crate::io::Raster::into_stored_heights`]
    /// gives them of the same image read whole.
    fn stored_scale(&self) -> (f64, bool) {
        (1.0, false)
    }

    /// The georeferencing of the file the rows come from, if it has any
    /// (a GeoTIFF's).
    fn georef(&self) -> Option<&crate::io::Georef> {
        None
    }

    /// Decodes the next row into `out` (`width` values).
    ///
    /// Errors: [`Error::Decode`](crate::Error::Decode) for corrupt or truncated data, or when all
    /// rows have been read.
    fn next_row(&mut self, out: &mut [f64]) -> Result<()>;

    /// Whether every value [`next_row`](Self::next_row) gives is an `f32`
    /// exactly (stored 8- and 16-bit integers, half and float samples; not
    /// luma, not 32-bit integers). A conversion then holds its rows as
    /// `f32`, half the memory and bandwidth, with the same bits.
    fn exact_in_f32(&self) -> bool {
        false
    }

    /// The next row as `f32`, for a source that is
    /// [`exact_in_f32`](Self::exact_in_f32) (otherwise the values round).
    ///
    /// Errors: as [`next_row`](Self::next_row).
    fn next_row_f32(&mut self, out: &mut [f32]) -> Result<()> {
        let mut row = zeroed::<f64>(out.len())?;
        self.next_row(&mut row)?;
        out.iter_mut().zip(&row).for_each(|(o, &v)| *o = v as f32);
        Ok(())
    }

    /// Reads every row, giving each to `visit` as heights in contract
    /// units, and returns the last `rows` rows (fewer if the image is
    /// shorter), as stored: the first pass of a conversion that wraps
    /// across the top and bottom.
    ///
    /// Errors: those of [`next_row`](Self::next_row); [`Error::Limits`](crate::Error::Limits)
    /// if the memory for the rows is not there.
    fn read_tail(mut self, rows: usize, mut visit: impl FnMut(&[f32])) -> Result<Vec<f64>>
    where
        Self: Sized,
    {
        let (w, h, unit) = (self.width(), self.height(), self.unit());
        let keep = rows.min(h);
        let mut tail = zeroed(keep * w)?;
        let mut row = zeroed(w)?;
        let mut heights = zeroed(w)?;
        for y in 0..h {
            self.next_row(&mut row)?;
            for (height, &value) in heights.iter_mut().zip(&row) {
                *height = (value * unit) as f32;
            }
            visit(&heights);
            if y + keep >= h {
                tail[(y + keep - h) * w..][..w].copy_from_slice(&row);
            }
        }
        Ok(tail)
    }
}

/// Rows as the values stored, for a fit in map units, which takes the
/// values as they are (a DEM's metres): each row value times
/// [`RowSource::stored_scale`], made whole again where the division left
/// a fraction of an integer (its error is under 2⁻²⁰), exactly as
/// [`crate::io::Raster::into_stored_heights`] computes them; the tiling
/// check's heights and an alpha of heights are then stored values too, as
/// a whole image's are. Rows already stored pass through untouched (in
/// `f32` where exact).
pub(crate) struct StoredRows<R> {
    rows: R,
    scale: f64,
    whole: bool,
}

impl<R: RowSource> StoredRows<R> {
    pub(crate) fn new(rows: R) -> Self {
        let (scale, whole) = rows.stored_scale();
        StoredRows { rows, scale, whole }
    }

    /// Row values of the wrapped source as the values stored.
    pub(crate) fn restore(&self, values: &mut [f64]) {
        let scale = self.scale;
        match (scale == 1.0, self.whole) {
            (true, _) => {}
            (false, true) => values.iter_mut().for_each(|v| *v = (*v * scale).round()),
            (false, false) => values.iter_mut().for_each(|v| *v *= scale),
        }
    }
}

impl<R: RowSource> RowSource for StoredRows<R> {
    fn width(&self) -> usize {
        self.rows.width()
    }

    fn height(&self) -> usize {
        self.rows.height()
    }

    fn unit(&self) -> f64 {
        1.0
    }

    fn georef(&self) -> Option<&crate::io::Georef> {
        self.rows.georef()
    }

    fn next_row(&mut self, out: &mut [f64]) -> Result<()> {
        self.rows.next_row(out)?;
        self.restore(out);
        Ok(())
    }

    fn exact_in_f32(&self) -> bool {
        self.scale == 1.0 && self.rows.exact_in_f32()
    }

    fn next_row_f32(&mut self, out: &mut [f32]) -> Result<()> {
        if self.scale == 1.0 {
            return self.rows.next_row_f32(out);
        }
        let mut row = zeroed::<f64>(out.len())?;
        self.next_row(&mut row)?;
        out.iter_mut().zip(&row).for_each(|(o, &v)| *o = v as f32);
        Ok(())
    }
}

/// `len` zeros, allocated fallibly: a row of a very wide image may not fit
/// in what the process may still take, which is an error, not an abort.
pub(crate) fn zeroed<T: Default + Clone>(len: usize) -> Result<Vec<T>> {
    let mut v = try_vec(len)?;
    v.resize(len, T::default());
    Ok(v)
}
