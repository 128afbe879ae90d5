//! Lit views of normal maps, for people to look at.
//!
//! A normal map's colours say little to the eye; the same normals lit by a
//! single raking light show the relief at once, and tiling the lit view 2×2
//! shows whether the seams match. The shading is Lambert's law with a
//! little ambient light, so faces turned away from the light stay grey
//! rather than black:
//!
//! ```text
//! L     = (cos e · cos a,  cos e · sin a,  sin e)      a = azimuth, e = elevation
//! value = AMBIENT + (1 − AMBIENT) · max(0, n · L)      in [0, 1], then × 255
//! ```
//!
//! n and L are in the OpenGL tangent frame: +x to the right (larger column
//! index), +y up the image (smaller row index), +z out of the surface.
//!
//! [`lit_view`] makes the picture of a decoded image as `normalfit shade`
//! does: a normal map's colours decoded ([`crate::normal_map`]), a height
//! map fitted first, the light applied, tiled if asked; [`LitView::encode`]
//! writes it as a gray PNG.

use std::borrow::Cow;
use std::io::{Seek, Write};
use std::path::{Path, PathBuf};

use crate::borders::{BorderChoices, Warning};
use crate::engine::{self, ConvertError, Input, Output, Place, Settings, Sink, Source, Stage, sink, write_to};
use crate::error::{Error, Result};
use crate::fit::checked_len;
use crate::io::encoding::{TiffDepth, TiffOptions};
use crate::io::{
    self, Channel, FileSet, Georef, OutputFormat, PngCompression, PngDepth, PngOptions, Raster, ReadOptions, Replace,
};
use crate::normal_map::{ImageKind, KindChoice};
use crate::options::Options;
use crate::units::MapSpacing;

pub use crate::light::{AMBIENT, Light, Sun, SunChoice, shade, shade_sun, tile_2x2};
pub(crate) use crate::light::{Lamp, Lighting, shade_with};

#[cfg(test)]
mod tests {
    use super::*;

    /// The command line's and Python's rule: a light, a sun angle (the
    /// other the default's), or neither; not both, nor an angle out of
    /// range.
    #[test]
    fn the_lighting_chosen_is_a_light_a_sun_or_the_default() {
        let base = LitOptions::new();
        let light = Light::new(45.0, 60.0).unwrap();
        let chosen = |l: Option<Light>, az: Option<f64>, alt: Option<f64>| base.clone().with_lighting(l, az, alt);
        let none = chosen(None, None, None).unwrap();
        assert_eq!((none.light, none.sun), (Light::default(), SunChoice::Georeferenced(Sun::default())));
        let lit = chosen(Some(light), None, None).unwrap();
        assert_eq!((lit.light, lit.sun), (light, SunChoice::Off));
        let sun = |az, alt| SunChoice::Always(Sun::new(az, alt).unwrap());
        assert_eq!(chosen(None, Some(200.0), None).unwrap().sun, sun(200.0, 45.0));
        assert_eq!(chosen(None, None, Some(30.0)).unwrap().sun, sun(315.0, 30.0));
        assert_eq!(chosen(None, Some(90.0), Some(10.0)).unwrap().sun, sun(90.0, 10.0));
        for (l, az, alt) in [(Some(light), Some(1.0), None), (Some(light), None, Some(1.0)), (None, None, Some(95.0))] {
            assert!(matches!(chosen(l, az, alt), Err(Error::InvalidOption(_))), "{l:?} {az:?} {alt:?}");
        }
    }
}

/// What [`lit_view`] does with an image.
#[derive(Clone, Debug)]
#[non_exhaustive]
pub struct LitOptions {
    /// The fit for height maps; its convention is also the one a normal
    /// map's green follows. Its borders are replaced by
    /// [`LitOptions::borders`]'.
    pub fit: Options,
    /// The border modes for height maps, fixed or `auto`.
    pub borders: BorderChoices,
    /// The light of the texture view, for inputs the sun does not light.
    pub light: Light,
    /// When the GIS sun lights the image instead ([`shade_sun`]).
    /// Default: [`SunChoice::Georeferenced`] with [`Sun::default`].
    pub sun: SunChoice,
    /// Repeat the picture 2×2, so seams show.
    pub tile: bool,
    /// Whether the image is a normal or a height map (detected by default).
    pub kind: KindChoice,
    /// The channel of a height map that holds the height.
    pub channel: Option<Channel>,
    /// A float normal map holds n itself, not (n + 1)/2.
    pub signed: bool,
    /// Fit height maps in real-world units ([`crate::Units::Map`]), the
    /// spacing from the file or given, as a conversion does
    /// ([`crate::convert::Conversion::map_units`]): heights as stored (a
    /// DEM's metres), texels as far apart as the ground says, so that at
    /// gain 1 the slopes, and the sun's hillshade, are the terrain's, as
    /// `gdaldem hillshade` draws them at its default `-z 1`. The fit's own
    /// [`Options::units`] are replaced by what this gives. Normal maps are
    /// lit as they are. Default: `None`, the contract's units.
    pub map_units: Option<MapSpacing>,
    /// Which existing files the view and its georeferencing sidecars may
    /// replace (default: any); checked before any is written, and they
    /// appear together.
    pub replace: Replace,
}

impl Default for LitOptions {
    fn default() -> Self {
        let fit = Options::new();
        LitOptions {
            borders: fit.borders.into(),
            fit,
            light: Light::default(),
            sun: SunChoice::Georeferenced(Sun::default()),
            tile: false,
            kind: KindChoice::Auto,
            channel: None,
            signed: false,
            map_units: None,
            replace: Replace::Always,
        }
    }
}

impl LitOptions {
    /// The defaults: the fit's defaults, the default light, not tiled,
    /// the kind detected.
    #[must_use]
    pub fn new() -> LitOptions {
        LitOptions::default()
    }

    /// Which existing files the view and its sidecars may replace.
    #[must_use]
    pub fn with_replace(mut self, replace: Replace) -> LitOptions {
        self.replace = replace;
        self
    }

    /// With this fit, its borders fixed as they are.
    #[must_use]
    pub fn with_fit(mut self, fit: Options) -> LitOptions {
        self.borders = fit.borders.into();
        self.fit = fit;
        self
    }

    /// With these border choices.
    #[must_use]
    pub fn with_borders(mut self, borders: BorderChoices) -> LitOptions {
        self.borders = borders;
        self
    }

    /// With this light, for every input (the sun off: a light given is
    /// the texture view's).
    #[must_use]
    pub fn with_light(mut self, light: Light) -> LitOptions {
        self.light = light;
        self.sun = SunChoice::Off;
        self
    }

    /// With this choice of sun.
    #[must_use]
    pub fn with_sun(mut self, sun: SunChoice) -> LitOptions {
        self.sun = sun;
        self
    }

    /// With the lighting a caller chose (`normalfit shade`'s `--light`,
    /// `--azimuth` and `--altitude`; Python's `lit_view`): a `light`, the
    /// texture view's for every input; else a sun angle, the GIS sun for
    /// every input (the other angle [`Sun::default`]'s); else neither, the
    /// default (the sun for georeferenced inputs, the default light for the
    /// others).
    ///
    /// Errors: [`Error::InvalidOption`] for a light and a sun angle both,
    /// or a sun angle out of range ([`Sun::new`]).
    pub fn with_lighting(
        self,
        light: Option<Light>,
        azimuth: Option<f64>,
        altitude: Option<f64>,
    ) -> Result<LitOptions> {
        match (light, azimuth, altitude) {
            (Some(_), Some(_), _) | (Some(_), _, Some(_)) => Err(Error::InvalidOption(
                "a light (the texture view's) or the sun's azimuth and altitude, not both".into(),
            )),
            (Some(light), None, None) => Ok(self.with_light(light)),
            (None, None, None) => Ok(self),
            (None, azimuth, altitude) => {
                let default = Sun::default();
                let sun = Sun::new(azimuth.unwrap_or(default.azimuth_deg), altitude.unwrap_or(default.altitude_deg))?;
                Ok(self.with_sun(SunChoice::Always(sun)))
            }
        }
    }

    /// The light or the sun, as chosen.
    pub(crate) fn lighting(&self) -> Lighting {
        Lighting { light: self.light, sun: self.sun }
    }

    /// The lamp for an image placed by `georef` (none: not georeferenced),
    /// in the fit's convention.
    pub(crate) fn lamp(&self, georef: Option<&crate::io::Georef>) -> Lamp {
        self.lighting().lamp(georef, self.fit.convention)
    }

    /// Tiled 2×2 (`true`) or not.
    #[must_use]
    pub fn with_tile(mut self, tile: bool) -> LitOptions {
        self.tile = tile;
        self
    }

    /// The image is this kind.
    #[must_use]
    pub fn with_kind(mut self, kind: KindChoice) -> LitOptions {
        self.kind = kind;
        self
    }

    /// Reading a height map's height from this channel.
    #[must_use]
    pub fn with_channel(mut self, channel: Option<Channel>) -> LitOptions {
        self.channel = channel;
        self
    }

    /// A float normal map holding n itself (`true`).
    #[must_use]
    pub fn with_signed(mut self, signed: bool) -> LitOptions {
        self.signed = signed;
        self
    }

    /// Fitting height maps in map units, the spacing from the file
    /// ([`MapSpacing::FromFile`]) or given; `None` for the contract's
    /// units. Front ends take it from `--units` and `--pixel-size` by
    /// [`MapSpacing::choose`].
    #[must_use]
    pub fn with_map_units(mut self, map_units: Option<MapSpacing>) -> LitOptions {
        self.map_units = map_units;
        self
    }
}

/// A lit picture: 8-bit gray, row-major.
#[derive(Clone, Debug)]
#[non_exhaustive]
pub struct LitView {
    /// The gray values.
    pub pixels: Vec<u8>,
    /// Columns (twice the image's when tiled).
    pub width: usize,
    /// Rows (twice the image's when tiled).
    pub height: usize,
    /// What the image was taken for.
    pub kind: ImageKind,
    /// For a height map, the warning about a wrap that draws a seam.
    pub warnings: Vec<Warning>,
    /// The georeferencing of the image (a GeoTIFF's), which the picture
    /// keeps when it is not tiled: [`LitView::write_file`] writes it beside.
    pub georef: Option<Georef>,
    /// Missing texels of a height map with holes (a nodata value, the
    /// fit's or the GeoTIFF's): grey 0, as `gdaldem hillshade` writes
    /// nodata (counted once, not per tile).
    pub missing: usize,
}

impl LitView {
    /// Writes the picture as an 8-bit gray PNG (balanced compression).
    ///
    /// Errors: those of [`io::encode_gray`].
    pub fn encode(&self, out: impl Write + Seek) -> Result<()> {
        let encoding = PngOptions::new(PngDepth::Eight).with_compression(PngCompression::Default).into();
        io::encode_gray(&self.pixels, self.width, self.height, &encoding, out)
    }

    /// Writes the picture as an 8-bit grey TIFF: a GeoTIFF with the
    /// image's georeferencing when it has any, and GDAL's nodata value 0,
    /// as `gdaldem hillshade` writes (missing texels are grey 0; lit ones
    /// are at least 1).
    ///
    /// Errors: those of [`io::encode_gray`]; [`Error::Unsupported`] in a
    /// build without the `tiff` feature.
    pub fn encode_tiff(&self, out: impl Write + Seek) -> Result<()> {
        let encoding = TiffOptions::new(TiffDepth::Eight).into();
        let size = (self.width, self.height);
        io::write::encode_gray_tagged(&self.pixels, size, &encoding, lit_tiff_tags(self.georef.as_ref()), out)
    }

    /// Writes the picture to the file `path`, whole or not at all, in the
    /// format [`lit_format`] gives: a TIFF ([`LitView::encode_tiff`]), or
    /// a PNG ([`LitView::encode`]) and beside it the georeferencing
    /// sidecars ([`io::sidecar`]) when it has any. Returns the sidecars
    /// written.
    ///
    /// Errors: those of [`lit_format`], of the encoders and of writing the
    /// files.
    pub fn write_file(&self, path: &Path) -> Result<Vec<PathBuf>> {
        let mut files = FileSet::new(Replace::Always);
        let sidecars = match (&self.georef, lit_format(path)?) {
            (_, OutputFormat::Tiff) => {
                files.write(path, |out| self.encode_tiff(out))?;
                Vec::new()
            }
            (georef, _) => {
                let sidecars = match georef {
                    Some(georef) => io::sidecar::write_sidecars(path, georef, None, &mut files)?,
                    None => Vec::new(),
                };
                files.write(path, |out| self.encode(out))?;
                sidecars
            }
        };
        files.commit()?;
        Ok(sidecars)
    }
}

/// The format of a lit view written to the file `path`: TIFF for a name
/// ending in `.tif` or `.tiff`, PNG for `.png` or no extension.
///
/// Errors: [`Error::Unsupported`] for any other name.
pub fn lit_format(path: &Path) -> Result<OutputFormat> {
    match OutputFormat::from_path(path) {
        Ok(None | Some(OutputFormat::Png)) => Ok(OutputFormat::Png),
        Ok(Some(OutputFormat::Tiff)) => Ok(OutputFormat::Tiff),
        _ => Err(Error::Unsupported("a lit view is written as PNG or TIFF: name the output .png or .tif".into())),
    }
}

/// A lit view's TIFF tags: the source's georeferencing, and nodata 0.
fn lit_tiff_tags(georef: Option<&Georef>) -> io::encoding::TiffTags<'_> {
    io::encoding::TiffTags { georef, nodata: Some(0.0) }
}

/// The lit picture of a decoded image (lit by the sun or the light as
/// [`LitOptions::sun`] says): a normal map's colours read back
/// ([`crate::normal_map::decode`]), or a height map's normals fitted with
/// `opts.fit` (`auto` borders and the warning about a wrap that draws a
/// seam from the tiling check, as a conversion does; in map units when
/// [`LitOptions::map_units`] says, the heights as stored); then lit in the
/// frame of `opts.fit.convention`, which [`shade`] undoes, so both
/// conventions light the same on screen.
///
/// Errors: those of [`crate::normal_map::kind_of`] and
/// [`crate::normal_map::decode`], of the fit, of
/// [`MapSpacing::units`] (map units of a file without georeferencing and
/// no pixel size given, …), and [`Error::InvalidOption`] for `signed` with
/// a height map.
pub fn lit_view(raster: &Raster, opts: &LitOptions) -> Result<LitView> {
    lit(Cow::Borrowed(raster), opts)
}

/// [`lit_view`] of a raster the caller gives up: in map units its stored
/// heights are taken out of it rather than copied.
///
/// Errors: those of [`lit_view`].
pub fn lit_view_owned(raster: Raster, opts: &LitOptions) -> Result<LitView> {
    lit(Cow::Owned(raster), opts)
}

fn lit(raster: Cow<'_, Raster>, opts: &LitOptions) -> Result<LitView> {
    let kind = crate::normal_map::kind_of(&raster, opts.kind, opts.channel.as_ref())?;
    if kind == ImageKind::Height {
        if opts.signed {
            return Err(signed_height_map());
        }
        // A height map goes through the engine, its pixels kept.
        let raster = raster.into_owned();
        let georef = if opts.tile { None } else { raster.georef.clone() };
        let read = ReadOptions::default();
        let run = engine::run(Source::whole(raster, None), opts.stage(false), no_file(), opts.settings(&read), &());
        let (summary, pixels) = run.map_err(Error::from)?;
        let scale = if opts.tile { 2 } else { 1 };
        return Ok(LitView {
            pixels: pixels.unwrap_or_default(),
            width: scale * summary.width,
            height: scale * summary.height,
            kind,
            warnings: summary.warnings,
            georef,
            missing: summary.missing,
        });
    }
    let (w, h) = (raster.width, raster.height);
    let georef = if opts.tile { None } else { raster.georef.clone() };
    let lamp = opts.lamp(raster.georef.as_ref());
    let normals = crate::normal_map::decode(&raster, opts.signed)?;
    let len = checked_len(w, h)?;
    if normals.len() != len {
        return Err(Error::BufferSize { expected: len, actual: normals.len() });
    }
    let lit = shade_with(&normals, lamp)?;
    let (pixels, width, height) = if opts.tile { (tile_2x2(&lit, w, h)?, 2 * w, 2 * h) } else { (lit, w, h) };
    Ok(LitView { pixels, width, height, kind, warnings: Vec::new(), georef, missing: 0 })
}

/// The error of `signed` with a height map.
fn signed_height_map() -> Error {
    Error::InvalidOption(
        "signed is for normal maps, and this is a height map (name its kind normal if it is not)".into(),
    )
}

/// A sink that keeps the pixels.
fn no_file<'a>() -> Sink<'a, 'a> {
    Sink { main: None, residual: None }
}

impl LitOptions {
    /// The engine's lit stage for these options (a TIFF or a PNG).
    fn stage(&self, tiff: bool) -> Stage {
        Stage::Lit { lighting: self.lighting(), tile: self.tile, tiff }
    }

    /// What the engine takes of the fit and the source.
    fn settings<'a>(&self, read: &'a ReadOptions) -> Settings<'a> {
        Settings {
            fit: self.fit.clone(),
            borders: self.borders,
            read,
            channel: self.channel.clone(),
            map_units: self.map_units,
            replace: self.replace,
            roughness_base: None,
            inputs: std::sync::Arc::default(),
        }
    }
}

/// [`lit_view`] of the image at `path`.
///
/// Errors: those of [`io::read_path`] and [`lit_view`].
pub fn lit_view_of_file(path: &Path, read: &ReadOptions, opts: &LitOptions) -> Result<LitView> {
    lit_view_owned(io::read_path(path, read)?, opts)
}

/// What [`lit_file`] did.
#[derive(Clone, Debug)]
#[non_exhaustive]
pub struct LitWritten {
    /// Columns of the picture (twice the image's when tiled).
    pub width: usize,
    /// Rows of the picture (twice the image's when tiled).
    pub height: usize,
    /// What the image was taken for.
    pub kind: ImageKind,
    /// The warning about a wrap that draws a seam, if any.
    pub warnings: Vec<Warning>,
    /// The georeferencing sidecars written beside a PNG picture.
    pub sidecars: Vec<PathBuf>,
    /// Missing texels (grey 0), as [`LitView::missing`].
    pub missing: usize,
    /// Whether the rows streamed (else the image was read whole).
    pub streamed: bool,
}

/// The lit view of the image `input` written to `output`, as
/// [`lit_view`] makes it, through the engine: a file (PNG, or TIFF for a
/// name ending in `.tif`/`.tiff`, [`lit_format`]) written whole or not at
/// all and never over the input, with the georeferencing sidecars beside
/// a PNG; or a writer, given a PNG. A GeoTIFF band's heights stream into a
/// file band by band (memory grows with the width, not the height),
/// unless tiled; every other image is read whole, and its kind looked at.
/// The picture is the same, grey for grey, either way.
///
/// Errors: [`Place::Input`] for reading, decoding and the fit (and
/// `signed` with a height map); [`Place::Output`] for a name that is no
/// format of a lit view, an output that is the input, and writing.
pub fn lit_file(
    input: Input<'_>,
    read: &ReadOptions,
    opts: &LitOptions,
    output: Output<'_>,
) -> Result<LitWritten, ConvertError> {
    let in_failure = ConvertError::at(Place::Input);
    let out_failure = ConvertError::at(Place::Output);
    let tiff = match output.path() {
        Some(path) => lit_format(path).map_err(&out_failure)? == OutputFormat::Tiff,
        None => false,
    };
    let stage = opts.stage(tiff);
    // Heights taken as such without a look at the whole image: a GeoTIFF
    // band (elevation), unless the caller says the image is a normal map.
    let may_stream = stage.streams_into(Some(&output)) && !opts.signed && opts.kind != KindChoice::Normal;
    let mut source = Source::open(input, read, opts.channel.clone(), may_stream).map_err(&in_failure)?;
    if source.streams() && !source.is_tiff_band() {
        source = source.into_whole(read).map_err(&in_failure)?;
    }
    let kind = match source.raster() {
        Some(raster) => crate::normal_map::kind_of(raster, opts.kind, opts.channel.as_ref()).map_err(&in_failure)?,
        None => ImageKind::Height,
    };
    if kind == ImageKind::Height {
        if opts.signed {
            return Err(in_failure(signed_height_map()));
        }
        let sink = Sink { main: Some(output), residual: None };
        let (summary, _) = engine::run(source, stage, sink, opts.settings(read), &())?;
        let scale = if opts.tile { 2 } else { 1 };
        return Ok(LitWritten {
            width: scale * summary.width,
            height: scale * summary.height,
            kind,
            warnings: summary.warnings,
            sidecars: summary.sidecars,
            missing: summary.missing,
            streamed: summary.streamed,
        });
    }
    // A normal map's colours, read back and lit.
    let input_path = source.path.clone();
    let Some(raster) = source.into_raster() else { unreachable!("a source read whole") };
    let view = lit_view_owned(raster, opts).map_err(&in_failure)?;
    sink::prepare(&output, input_path.as_deref()).map_err(&out_failure)?;
    let path = output.path().map(Path::to_path_buf);
    let mut files = FileSet::new(opts.replace);
    let sidecars = match (&view.georef, path, tiff) {
        (Some(georef), Some(path), false) => {
            io::sidecar::write_sidecars(&path, georef, input_path.as_deref(), &mut files).map_err(&out_failure)?
        }
        _ => Vec::new(),
    };
    write_to(output, &mut files, |out| if tiff { view.encode_tiff(out) } else { view.encode(out) })
        .map_err(&out_failure)?;
    files.commit().map_err(&out_failure)?;
    Ok(LitWritten {
        width: view.width,
        height: view.height,
        kind,
        warnings: view.warnings,
        sidecars,
        missing: view.missing,
        streamed: false,
    })
}
