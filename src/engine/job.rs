//! A run under way: the whole image, or its rows as they stream, through
//! the stage into the sink.

use std::path::Path;

use super::sink::{
    self, InMemory, Output, check_assembly_memory, check_whole_memory, encode_residual, write_all, write_to, zeroed,
};
use super::source::{Reopen, Rows};
use super::stage::{Texels, fitted, with_holes};
use super::{ConvertError, MipStage, Observer, Place, Settings, Sink, Stage, Summary, chain_files};
use crate::borders::{BorderChoice, Warning};
use crate::error::Error;
use crate::io::encoding::TiffTags;
use crate::io::gpu::{self, Chain};
use crate::io::{self, Encoding, FileSet, Georef, Layout, OutputFormat, Raster};
use crate::light::Grey;
use crate::light::Lighting;
use crate::mips::{MipChoice, MipLevel};
use crate::normal_map::{ImageKind, KindChoice, kind_of};
use crate::pipeline::{self, StoredRows};
use crate::samples::Samples;
use crate::samples::with_slice;
use crate::tiling::{HeightSeams, TilingOptions, TilingReport};
use crate::{Border, Options};

/// One run under way.
pub(super) struct Job<'a> {
    pub(super) settings: &'a Settings<'a>,
    pub(super) stage: Stage,
    /// The input file, which no output may replace.
    pub(super) input: Option<&'a Path>,
    pub(super) encoding: Encoding,
    /// The input's georeferencing, which a TIFF output keeps.
    pub(super) georef: Option<&'a Georef>,
    pub(super) observer: &'a dyn Observer,
    /// A lit view's pixels, when no file takes them.
    pub(super) pixels: Option<Vec<u8>>,
    pub(super) summary: Summary,
    /// The files written so far, named together when the run is done.
    pub(super) files: FileSet,
}

impl Job<'_> {
    /// What a TIFF output holds besides its samples: the input's
    /// georeferencing.
    fn tiff_tags(&self) -> TiffTags<'_> {
        match self.stage {
            // GDAL's nodata: missing texels are grey 0, lit ones at least 1.
            Stage::Lit { tile, .. } => TiffTags { georef: if tile { None } else { self.georef }, nodata: Some(0.0) },
            Stage::Normals(_) | Stage::Mips(_) | Stage::Curvature { .. } => {
                TiffTags { georef: self.georef, nodata: None }
            }
            // gdaldem's: holes, and a flat texel's aspect.
            Stage::Terrain { .. } => TiffTags { georef: self.georef, nodata: Some(crate::units::NODATA.into()) },
        }
    }

    fn warn(&mut self, warning: Warning) {
        self.observer.warning(&warning);
        self.summary.warnings.push(warning);
    }

    /// The streamed tiling check of a `width` × `height` image, or `None`
    /// with a warning when its memory is not there: the check only warns
    /// about a wrap that draws a seam. `auto` borders need its verdict, so
    /// there the lack of memory is an error. Texels equal to `nodata` (as
    /// the heights pushed hold it) and non-finite ones are holes, skipped.
    fn seam_check(
        &mut self,
        width: usize,
        height: usize,
        nodata: Option<f64>,
    ) -> Result<Option<HeightSeams>, ConvertError> {
        match HeightSeams::new(width, height) {
            Ok(seams) => Ok(Some(seams.with_nodata(nodata))),
            Err(e) if self.settings.borders.any_auto() => Err(ConvertError { place: Place::Input, error: e }),
            Err(e) => {
                self.warn(Warning::SeamCheckSkipped(e.to_string()));
                Ok(None)
            }
        }
    }

    /// Records the tiling check and warns about a wrap that draws a seam.
    fn judge(&mut self, report: TilingReport) {
        if let Some(warning) = self.settings.borders.seams(&report) {
            self.warn(warning);
        }
        self.summary.tiling = Some(report);
    }

    /// Settles the borders (`auto` by the tiling check) and gives the
    /// fit's options.
    fn fit_options(&mut self) -> Options {
        let borders = self.settings.borders.resolve(self.summary.tiling.as_ref());
        self.summary.borders = borders;
        self.settings.fit.clone().with_borders(borders)
    }

    /// Refuses a file output that is the input file, and makes its folder
    /// if asked to ([`sink::prepare`]).
    fn prepare(&self, output: &Output<'_>, place: Place) -> Result<(), ConvertError> {
        sink::prepare(output, self.input).map_err(ConvertError::at(place))
    }

    /// The heights of a whole image in the units the fit takes (holes,
    /// map units), the tiling check run when the borders need it, and the
    /// fit's options with the borders settled.
    fn heights_and_fit(&mut self, raster: Raster) -> Result<(Samples, Options), ConvertError> {
        let (width, height) = (raster.width, raster.height);
        (self.summary.width, self.summary.height) = (width, height);
        let conversion = self.settings;
        let in_failure = ConvertError::at(Place::Input);
        let units = match &conversion.map_units {
            Some(map) => Some(map.units(raster.georef.as_ref(), height).map_err(&in_failure)?),
            None => None,
        };
        let mut fit_nodata = conversion.fit.nodata;
        let heights = match (units.is_some(), conversion.fit.nodata) {
            (stored, Some(nodata)) => {
                let channel = conversion.channel.clone();
                let (heights, nodata) = raster.into_heights_with_holes(channel, stored, nodata).map_err(&in_failure)?;
                fit_nodata = Some(nodata);
                heights
            }
            (true, None) => raster.into_stored_heights(conversion.channel.clone()).map_err(&in_failure)?,
            // The lit view fits heights in contract units, as f32, as it
            // always has (its greys are those of that fit).
            (false, None) if matches!(self.stage, Stage::Lit { .. }) => {
                Samples::F32(raster.heights(conversion.channel.clone()).map_err(&in_failure)?)
            }
            (false, None) => raster.into_heights(conversion.channel.clone()).map_err(&in_failure)?,
        };
        let report = match conversion.borders.needs_check() {
            true => match self.seam_check(width, height, fit_nodata)? {
                Some(mut seams) => {
                    seams.push_samples(&heights).map_err(&in_failure)?;
                    Some(seams.finish(&TilingOptions::new().with_kind(KindChoice::Height)).map_err(&in_failure)?)
                }
                None => None,
            },
            false => None,
        };
        if let Some(report) = report {
            self.judge(report);
        }
        let mut fit = self.fit_options().with_nodata(fit_nodata);
        if let Some(units) = units {
            fit = fit.with_units(units);
        }
        Ok((heights, fit))
    }

    /// The whole-image conversion: the heights in memory, fitted straight
    /// into the output's texel type.
    fn whole(
        &mut self,
        raster: Raster,
        normals: Option<Output<'_>>,
        residual: Option<(Output<'_>, OutputFormat)>,
    ) -> Result<(), ConvertError> {
        if let Stage::Mips(stage) = self.stage {
            if residual.is_some() {
                let problem = "a residual map is not made beside a mip chain";
                return Err(ConvertError { place: Place::Residual, error: Error::InvalidOption(problem.into()) });
            }
            return self.mips_whole(raster, stage, normals);
        }
        let (width, height) = (raster.width, raster.height);
        let (heights, fit) = self.heights_and_fit(raster)?;
        let in_failure = ConvertError::at(Place::Input);
        if let Stage::Curvature { encoding, range } = self.stage {
            if residual.is_some() {
                let problem = "a residual map is made beside normals, not beside curvature";
                return Err(ConvertError { place: Place::Residual, error: Error::InvalidOption(problem.into()) });
            }
            return self.curvature_whole(&heights, (width, height), &fit, (encoding, range), normals);
        }
        if let Stage::Terrain { measure, encoding } = self.stage {
            if residual.is_some() {
                let problem = "a residual map is made beside normals, not beside a slope or an aspect map";
                return Err(ConvertError { place: Place::Residual, error: Error::InvalidOption(problem.into()) });
            }
            return self.terrain_whole(&heights, (width, height), &fit, (measure, encoding), normals);
        }
        if let Stage::Lit { lighting, tile, .. } = self.stage {
            return self.lit_whole(&heights, (width, height), &fit, (lighting, tile), normals);
        }
        let to_writer = matches!(normals, Some(Output::Writer(_)));
        let holes = fit.nodata.is_some();
        let work = crate::fit::work_bytes(&fit, (width, height), heights.unit(), holes, residual.is_some())
            .map_err(&in_failure)?;
        let outputs = (normals.is_some(), residual.is_some(), holes);
        // Named by the input, as a streamed conversion's bands are.
        check_whole_memory(&self.encoding, to_writer, outputs, (width, height), work).map_err(&in_failure)?;
        let mut distances = residual.as_ref().map(|_| zeroed::<f32>(heights.len())).transpose().map_err(&in_failure)?;
        let mut valid = match fit.nodata {
            Some(_) => Some(zeroed::<bool>(heights.len()).map_err(&in_failure)?),
            None => None,
        };
        let texels =
            Texels::fit(&heights, width, height, &fit, &self.encoding, distances.as_deref_mut(), valid.as_deref_mut())
                .map_err(&in_failure)?;
        self.summary.missing = valid.as_ref().map_or(0, |v| v.iter().filter(|&&v| !v).count());
        // An alpha of heights takes them in contract units, as f32; an
        // alpha of validity, 1 and 0.
        let heights = match (self.encoding.layout(), &valid) {
            (Layout::RgbValid, valid) => {
                let mut alpha = crate::samples::try_vec(width * height).map_err(&in_failure)?;
                match valid {
                    Some(valid) => alpha.extend(valid.iter().map(|&v| if v { 1.0 } else { 0.0 })),
                    None => alpha.resize(width * height, 1.0),
                }
                alpha
            }
            (layout, valid) if layout.needs_heights() => {
                let mut alpha = heights.into_f32().map_err(&in_failure)?;
                if let Some(valid) = valid {
                    crate::pipeline::zero_missing(&mut alpha, valid);
                }
                alpha
            }
            _ => Vec::new(),
        };
        if let Some(out) = &normals {
            self.prepare(out, Place::Output)?;
        }
        if let Some((out, _)) = &residual {
            self.prepare(out, Place::Residual)?;
        }
        let mut files = std::mem::take(&mut self.files);
        let (encoding, tags) = (self.encoding, self.tiff_tags());
        if let Some(out) = normals {
            write_to(out, &mut files, |w| texels.encode(&heights, (width, height), &encoding, tags, w))
                .map_err(ConvertError::at(Place::Output))?;
        }
        if let (Some((out, format)), Some(distances)) = (residual, &distances) {
            let scale = fit.scale_for_width(width);
            write_to(out, &mut files, |w| encode_residual(distances, (width, height), scale, (format, tags), w))
                .map_err(ConvertError::at(Place::Residual))?;
        }
        self.files = files;
        Ok(())
    }

    /// A mip chain of the whole image: fitted from its heights, or averaged
    /// from a normal map's normals, with an alpha of each level's heights
    /// if asked; written as one texture, or an image a level
    /// ([`level_path`]); its roughness beside ([`roughness_path`]). Every
    /// file is checked before the chain is made ([`chain_files`]): none
    /// may be an input, and the policy must let each be written.
    fn mips_whole(&mut self, raster: Raster, stage: MipStage, out: Option<Output<'_>>) -> Result<(), ConvertError> {
        let (width, height) = (raster.width, raster.height);
        (self.summary.width, self.summary.height) = (width, height);
        let in_failure = ConvertError::at(Place::Input);
        let Some(out) = out else {
            let problem = "nothing to write: no output given";
            return Err(ConvertError { place: Place::Output, error: Error::InvalidOption(problem.into()) });
        };
        let encoding = stage.encoding;
        let texture = matches!(encoding, Encoding::Texture(_));
        let count = if stage.all { crate::mips::level_sizes(width, height).len() } else { 1 };
        if encoding.layout() == Layout::RgbValid {
            let problem = "mip levels hold no alpha of validity: leave the alpha out";
            return Err(ConvertError { place: Place::Output, error: Error::InvalidOption(problem.into()) });
        }
        // Where every file goes, each checked before any work.
        let files = match &out {
            Output::File { path, .. } => chain_files(path, texture, count, stage.roughness),
            Output::Writer(_) if stage.roughness => {
                let problem = "a roughness chain beside a writer needs its own file: name the output";
                return Err(ConvertError { place: Place::Roughness, error: Error::InvalidOption(problem.into()) });
            }
            Output::Writer(_) if !texture && count > 1 => {
                let problem = "mip levels written as images need a file: each level is a file of its own";
                return Err(ConvertError { place: Place::Output, error: Error::InvalidOption(problem.into()) });
            }
            Output::Writer(_) => Vec::new(),
        };
        for (k, (path, place)) in files.iter().enumerate() {
            let named = |e: Error| match e {
                // The first file is the output's own name; the others are named.
                Error::InvalidOption(problem) if k > 0 => {
                    Error::InvalidOption(format!("{}: {problem}", path.display()))
                }
                e => e,
            };
            sink::refuse_input(path, self.input).map_err(named).map_err(ConvertError::at(*place))?;
            self.files.check(path).map_err(ConvertError::at(*place))?;
        }
        let channel = self.settings.channel.as_ref();
        let average = match (stage.all, stage.choice) {
            (false, _) | (true, MipChoice::Fit) => false,
            (true, MipChoice::Average) => true,
            (true, MipChoice::Auto) => {
                kind_of(&raster, KindChoice::Auto, channel).map_err(&in_failure)? == ImageKind::Normal
            }
        };
        if stage.all
            && stage.choice == MipChoice::Fit
            && kind_of(&raster, KindChoice::Auto, channel).map_err(&in_failure)? == ImageKind::Normal
        {
            let problem = "is a normal map: a fitted mip chain needs a height map (average its normals instead, \
                           or name the height channel)";
            return Err(in_failure(Error::InvalidOption(problem.into())));
        }
        let with_heights = encoding.layout() == Layout::RgbHeight;
        if average && with_heights {
            let problem = "is a normal map: an alpha of heights needs a height map (leave the alpha out)";
            return Err(in_failure(Error::InvalidOption(problem.into())));
        }
        // The normals (12 bytes a texel, a third more for the levels), the
        // heights box-filtered (8 a level texel, twice), the texture's or
        // the level's bytes; an alpha of heights: their levels (8 a texel
        // while made, 4 kept).
        let texels = (width as u64).saturating_mul(height as u64);
        let per_texel = 16 + 24 + 8 + if with_heights { 16 } else { 0 };
        io::check_memory("making the mip chain", texels.saturating_mul(per_texel)).map_err(&in_failure)?;
        let (chain, alpha) = if average {
            let normals = crate::normal_map::decode(&raster, false).map_err(&in_failure)?;
            drop(raster);
            (crate::mips::average_chain(&normals, (width, height)).map_err(&in_failure)?, None)
        } else {
            let (heights, fit) = self.heights_and_fit(raster)?;
            let work = crate::fit::work_bytes(&fit, (width, height), heights.unit(), fit.nodata.is_some(), false)
                .map_err(&in_failure)?;
            io::check_memory("fitting the mip chain", texels.saturating_mul(per_texel).saturating_add(work))
                .map_err(&in_failure)?;
            let chain = if stage.all {
                with_slice!(&heights, h => crate::mips::fit_chain(h, (width, height), &fit)).map_err(&in_failure)?
            } else {
                let texels =
                    fitted::<[f32; 3]>(&heights, (width, height), crate::FitRequest::new(&fit)).map_err(&in_failure)?;
                vec![MipLevel { width, height, texels }]
            };
            let alpha = match with_heights {
                true => Some(
                    with_slice!(&heights, h => crate::mips::height_levels(h, (width, height), fit.nodata, count))
                        .map_err(&in_failure)?,
                ),
                false => None,
            };
            (chain, alpha)
        };
        let roughness = match stage.roughness {
            false => None,
            true => {
                let mut lengths = crate::mips::mean_lengths(&chain[0].texels, (width, height)).map_err(&in_failure)?;
                lengths.truncate(chain.len());
                let base = match self.settings.roughness_base {
                    Some(path) => Some(read_base(path, self.settings.read, (width, height))?),
                    None => None,
                };
                Some(crate::mips::roughness_chain(&lengths, base.as_deref()).map_err(&in_failure)?)
            }
        };
        let mut set = std::mem::take(&mut self.files);
        let tags = self.tiff_tags();
        let out_failure = ConvertError::at(Place::Output);
        let create_folder = matches!(out, Output::File { create_folder: true, .. });
        let mut next = files.iter();
        if let Encoding::Texture(texture) = encoding {
            let normals = match &alpha {
                Some(alpha) => Chain::NormalsAlpha(&chain, alpha),
                None => Chain::Normals(&chain),
            };
            let encoded = gpu::encode_chain(normals, texture.compression).map_err(&out_failure)?;
            let rough = match &roughness {
                Some(levels) => Some(
                    gpu::encode_chain(Chain::Values(levels), texture.values())
                        .map_err(ConvertError::at(Place::Roughness))?,
                ),
                None => None,
            };
            let main = match out {
                Output::Writer(writer) => Output::Writer(writer),
                Output::File { .. } => file(&next.next().expect("the texture's file").0, create_folder),
            };
            self.prepare(&main, Place::Output)?;
            write_to(main, &mut set, |w| gpu::write_encoded(w, &encoded, texture.container)).map_err(&out_failure)?;
            if let (Some(encoded), Some((path, place))) = (rough, next.next()) {
                self.prepare(&file(path, create_folder), *place)?;
                write_to(file(path, create_folder), &mut set, |w| gpu::write_encoded(w, &encoded, texture.container))
                    .map_err(ConvertError::at(*place))?;
            }
        } else {
            let alpha_of = |k: usize| alpha.as_ref().map(|a| &a[k].texels[..]);
            if let Output::Writer(writer) = out {
                // One level, no roughness: checked above.
                let level = &chain[0];
                let size = (level.width, level.height);
                write_to(Output::Writer(writer), &mut set, |w| {
                    io::write::encode_normals_tagged(&level.texels, alpha_of(0), size, &encoding, tags, w)
                })
                .map_err(&out_failure)?;
            } else {
                for (k, (level, (path, place))) in chain.iter().zip(next.by_ref()).enumerate() {
                    self.prepare(&file(path, create_folder), *place)?;
                    let size = (level.width, level.height);
                    write_to(file(path, create_folder), &mut set, |w| {
                        io::write::encode_normals_tagged(&level.texels, alpha_of(k), size, &encoding, tags, w)
                    })
                    .map_err(ConvertError::at(*place))?;
                }
                let format = encoding.format();
                for (level, (path, place)) in roughness.iter().flatten().zip(next) {
                    self.prepare(&file(path, create_folder), *place)?;
                    let size = (level.width, level.height);
                    write_to(file(path, create_folder), &mut set, |w| {
                        encode_residual(&level.texels, size, 1.0, (format, tags), w)
                    })
                    .map_err(ConvertError::at(*place))?;
                }
            }
        }
        self.files = set;
        Ok(())
    }

    /// A PNG or scan-line EXR file converted without holding the image:
    /// rows stream from the decoder through the fit to the encoder. One
    /// pass over the input, but for a wrap in y into an output written in
    /// order (EXR, or PNG into a writer), which needs the image's last rows
    /// first: an EXR gives them from its last blocks, a PNG by a first
    /// pass; and for `auto` borders, whose borders depend on the tiling
    /// check, which then comes from a first pass too.
    fn streaming<S: Reopen>(&mut self, rows: S, input: &Path, out: Output<'_>) -> Result<(), ConvertError> {
        let conversion = self.settings;
        let (read, channel) = (&conversion.read, || conversion.channel.clone());
        let in_failure = ConvertError::at(Place::Input);
        let (width, height, r) = (rows.width(), rows.height(), conversion.fit.largest_patch() / 2);
        // Map units' spacing first: a file without one is refused before
        // any pass over it and before the output is looked at, as a whole
        // image is.
        let units = match &conversion.map_units {
            Some(map) => Some(map.units(rows.georef(), height).map_err(&in_failure)?),
            None => None,
        };
        self.prepare(&out, Place::Output)?;
        self.summary.streamed = true;
        (self.summary.width, self.summary.height) = (width, height);
        let borders = conversion.borders;
        let auto = borders.any_auto();
        let may_wrap_y = matches!(borders.y, BorderChoice::Auto | BorderChoice::Fixed(Border::Wrap));
        // A PNG file takes its top rows last, in room kept after the header.
        let png_file = matches!(out, Output::File { .. }) && matches!(self.encoding, Encoding::Png(_));
        let needs_tail = may_wrap_y && !png_file;
        // The nodata value as the rows hold it: holes to the tiling check.
        let row_nodata = conversion.fit.nodata.map(|v| rows.row_value(v));
        let check_opts = TilingOptions::new().with_kind(KindChoice::Height);
        let cheap_tail = if needs_tail && !auto { S::last_rows(input, read, channel(), r) } else { None };
        let (report, tail) = match cheap_tail {
            Some(tail) => (None, Some(tail.map_err(&in_failure)?)),
            None if auto || needs_tail => {
                let first = S::reopen(input, read, channel()).map_err(&in_failure)?;
                let first =
                    first.ok_or_else(|| in_failure(std::io::Error::other("changed while being read").into()))?;
                let mut seams = self.seam_check(width, height, row_nodata)?;
                let tail = first
                    .read_tail(r, |row| {
                        // Whole rows from the decoder, at most `height` of
                        // them: the check takes every one.
                        if let Some(s) = seams.as_mut() {
                            let _ = s.push_row(row);
                        }
                    })
                    .map_err(&in_failure)?;
                (seams.map(|s| s.finish(&check_opts)).transpose().map_err(&in_failure)?, Some(tail))
            }
            None => (None, None),
        };
        // Without a first pass, the check runs on the rows as they stream
        // and the warning comes after the output.
        if let Some(report) = report {
            self.judge(report);
        }
        let mut fit = self.fit_options();
        if let Some(units) = units {
            fit = fit.with_units(units);
        }
        // The nodata value as the rows hold it.
        let fit = fit.clone().with_nodata(fit.nodata.map(|v| rows.row_value(v)));
        let tail = if fit.borders.y == Border::Wrap { tail.as_deref() } else { None };
        let mut seams = match self.summary.tiling.is_none() && borders.needs_check() {
            true => self.seam_check(width, height, row_nodata)?,
            false => None,
        };
        let observer = self.observer;
        observer.size(width, height);
        let visit = |row: &[f32]| {
            observer.row();
            // Whole rows from the decoder, at most `height` of them: the
            // check takes every one.
            if let Some(s) = seams.as_mut() {
                let _ = s.push_row(row);
            }
        };
        // Decoding and fitting fail on the input; writing, on the output.
        let mut input_failed = false;
        let mut on_input = |e: &Error| {
            if !matches!(e, Error::Io(_) | Error::Encode(_)) {
                input_failed = true;
            }
        };
        let (w, h) = (width, height);
        let mut missing = 0;
        let mut files = std::mem::take(&mut self.files);
        #[cfg(feature = "tiff")]
        let tags = self.tiff_tags();
        let lamp = match self.stage {
            Stage::Lit { lighting, .. } => Some(lighting.lamp(self.georef, fit.convention)),
            Stage::Normals(_) | Stage::Mips(_) | Stage::Curvature { .. } | Stage::Terrain { .. } => None,
        };
        let measure = match self.stage {
            Stage::Terrain { measure, .. } => Some(measure),
            _ => None,
        };
        #[cfg(feature = "tiff")]
        let affine = self.georef.and_then(crate::io::Georef::affine);
        let (curvature, range) = match self.stage {
            Stage::Curvature { range, .. } => (true, range),
            _ => (false, 0.0),
        };
        let result = match (lamp, out, self.encoding) {
            // A slope or an aspect map streams into a TIFF file alone
            // ([`Stage::streams_into`]); `run` reads the others whole.
            #[cfg(feature = "tiff")]
            (None, Output::File { path, .. }, Encoding::Tiff(_)) if measure.is_some() => files.write(path, |file| {
                if let Some(measure) = measure {
                    missing = pipeline::measure_tiff(rows, tail, &fit, (measure, affine.as_ref()), tags, visit, file)
                        .inspect_err(&mut on_input)?;
                }
                Ok(())
            }),
            (None, _, _) if measure.is_some() => Err(Error::InvalidOption(
                "a slope or an aspect map streams into a TIFF file only: read it whole".into(),
            )),
            // The lit view streams into a file alone ([`Stage::streams_into`]).
            (Some(lamp), Output::File { path, .. }, Encoding::Png(_)) => files.write(path, |file| {
                missing = pipeline::shade_png_seekable(rows, &fit, lamp, visit, file).inspect_err(&mut on_input)?;
                Ok(())
            }),
            #[cfg(feature = "tiff")]
            (Some(lamp), Output::File { path, .. }, Encoding::Tiff(_)) => files.write(path, |file| {
                missing = pipeline::shade_tiff(rows, tail, &fit, lamp, tags, visit, file).inspect_err(&mut on_input)?;
                Ok(())
            }),
            (Some(_), _, _) => Err(Error::InvalidOption("a lit view streams into a file only: read it whole".into())),
            // The curvature streams into an EXR or PNG file alone ([`Stage::streams_into`]).
            (None, Output::File { path, .. }, Encoding::Exr(options)) if curvature => files.write(path, |file| {
                missing =
                    pipeline::curvature_exr(rows, tail, &fit, options.depth, visit, file).inspect_err(&mut on_input)?;
                Ok(())
            }),
            (None, Output::File { path, .. }, Encoding::Png(o)) if curvature => files.write(path, |file| {
                missing = pipeline::curvature_png_seekable(rows, &fit, (o.depth, o.compression), range, visit, file)
                    .inspect_err(&mut on_input)?;
                Ok(())
            }),
            (None, _, _) if curvature => {
                Err(Error::InvalidOption("a curvature map streams into an EXR or PNG file only: read it whole".into()))
            }
            (None, Output::File { path, .. }, Encoding::Exr(options)) => files.write(path, |file| {
                missing = pipeline::convert_exr_counting(rows, tail, &fit, options, visit, file)
                    .inspect_err(&mut on_input)?;
                Ok(())
            }),
            (None, Output::Writer(writer), Encoding::Exr(options)) => {
                // EXR seeks back to its offset table: the file is assembled
                // first, and must leave the stream room to work.
                let mut bytes = InMemory::default();
                check_assembly_memory(&self.encoding, w, h)
                    .and_then(|()| pipeline::convert_exr_counting(rows, tail, &fit, options, visit, &mut bytes))
                    .inspect_err(&mut on_input)
                    .and_then(|m| {
                        missing = m;
                        write_all(writer, bytes.0.get_ref())
                    })
            }
            (None, Output::File { path, .. }, Encoding::Png(options)) => files.write(path, |file| {
                missing = pipeline::convert_png_seekable_counting(rows, &fit, options, visit, file)
                    .inspect_err(&mut on_input)?;
                Ok(())
            }),
            (None, Output::Writer(writer), Encoding::Png(options)) => {
                pipeline::convert_png_counting(rows, tail, &fit, options, visit, writer)
                    .inspect_err(&mut on_input)
                    .map(|m| missing = m)
            }
            #[cfg(feature = "tiff")]
            (None, Output::File { path, .. }, Encoding::Tiff(options)) => files.write(path, |file| {
                missing = pipeline::convert_tiff_counting(rows, tail, &fit, options, tags, visit, file)
                    .inspect_err(&mut on_input)?;
                Ok(())
            }),
            #[cfg(feature = "tiff")]
            (None, Output::Writer(writer), Encoding::Tiff(options)) => {
                // TIFF seeks back to its directory's offset: the file is
                // assembled first, as an EXR is.
                let mut bytes = InMemory::default();
                check_assembly_memory(&self.encoding, w, h)
                    .and_then(|()| pipeline::convert_tiff_counting(rows, tail, &fit, options, tags, visit, &mut bytes))
                    .inspect_err(&mut on_input)
                    .and_then(|m| {
                        missing = m;
                        write_all(writer, bytes.0.get_ref())
                    })
            }
            #[cfg(not(feature = "tiff"))]
            (None, _, Encoding::Tiff(_)) => Err(io::write::no_tiff()),
            (None, _, Encoding::Texture(_)) => Err(io::write::not_a_chain()),
        };
        self.summary.missing = missing;
        let place = if input_failed { Place::Input } else { Place::Output };
        result.map_err(ConvertError::at(place))?;
        self.files = files;
        // A failed write stopped the rows part way: no seams to judge.
        if let Some(seams) = seams {
            self.judge(seams.finish(&check_opts).map_err(ConvertError::at(Place::Input))?);
        }
        Ok(())
    }

    /// Runs the stage on `rows` into `sink`: streamed, or whole.
    pub(super) fn run(&mut self, rows: Rows, sink: Sink<'_, '_>) -> Result<(), ConvertError> {
        let Sink { main, residual } = sink;
        let stored = self.settings.map_units.is_some();
        // A mip chain needs the whole image; the curvature, a slope or
        // aspect map and a lit view need it where they cannot stream into
        // their output (a TIFF or a stream for the curvature, an EXR or a
        // stream for a slope, a tiled view): a file opened to stream is
        // then read whole.
        let whole = match self.stage {
            Stage::Mips(_) => true,
            Stage::Normals(_) => false,
            Stage::Curvature { .. } | Stage::Terrain { .. } | Stage::Lit { .. } => {
                !self.stage.streams_into(main.as_ref())
            }
        };
        let rows = match rows {
            Rows::Png(_, input) | Rows::Exr(_, input) if whole => Rows::Whole(Box::new(
                io::read_path(&input, self.settings.read).map_err(ConvertError::at(Place::Input))?,
            )),
            #[cfg(feature = "tiff")]
            Rows::Tiff(_, input) if whole => Rows::Whole(Box::new(
                io::read_path(&input, self.settings.read).map_err(ConvertError::at(Place::Input))?,
            )),
            rows => rows,
        };
        match (rows, main) {
            (Rows::Whole(raster), main) => self.whole(*raster, main, residual),
            (_, None) => {
                let problem = "nothing to write: no output given";
                Err(ConvertError { place: Place::Output, error: Error::InvalidOption(problem.into()) })
            }
            // Map units fit the values as stored (a DEM's metres).
            (Rows::Png(rows, input), Some(out)) if stored => self.streaming(StoredRows::new(*rows), &input, out),
            (Rows::Png(rows, input), Some(out)) => self.streaming(*rows, &input, out),
            (Rows::Exr(rows, input), Some(out)) if stored => self.streaming(StoredRows::new(*rows), &input, out),
            (Rows::Exr(rows, input), Some(out)) => self.streaming(*rows, &input, out),
            #[cfg(feature = "tiff")]
            (Rows::Tiff(rows, input), Some(out)) if stored => self.streaming(StoredRows::new(*rows), &input, out),
            #[cfg(feature = "tiff")]
            (Rows::Tiff(rows, input), Some(out)) => self.streaming(*rows, &input, out),
        }
    }

    /// The lit view of the whole image: its normals lit by the lamp, holes
    /// grey 0 (as `gdaldem hillshade` writes nodata), tiled 2×2 if asked;
    /// encoded into `out`, or kept as pixels.
    fn lit_whole(
        &mut self,
        heights: &Samples,
        (width, height): (usize, usize),
        fit: &Options,
        (lighting, tile): (Lighting, bool),
        out: Option<Output<'_>>,
    ) -> Result<(), ConvertError> {
        let in_failure = ConvertError::at(Place::Input);
        let texels = (width as u64).saturating_mul(height as u64);
        // The greys, made in the fit's loop (1 byte a texel), the
        // validity (1), the greys tiled four times over (4); and the fit's
        // own work, which grows with N.
        let per_texel = 1 + 1 + if tile { 4 } else { 0 };
        let holes = fit.nodata.is_some();
        let work = crate::fit::work_bytes(fit, (width, height), heights.unit(), holes, false).map_err(&in_failure)?;
        io::check_memory("lighting the view", texels.saturating_mul(per_texel).saturating_add(work))
            .map_err(&in_failure)?;
        let mut valid = match fit.nodata {
            Some(_) => Some(zeroed::<bool>(heights.len()).map_err(&in_failure)?),
            None => None,
        };
        let lamp = lighting.lamp(self.georef, fit.convention);
        let request = with_holes(crate::FitRequest::new(fit), None, valid.as_deref_mut()).lit(lamp);
        // The texels' buffer becomes the greys' (in place: the same size).
        fn bytes<const SUN: bool>(greys: Vec<Grey<SUN>>) -> Vec<u8> {
            greys.into_iter().map(|g| g.0).collect()
        }
        let greys = match lamp.is_sun() {
            true => fitted(heights, (width, height), request).map(bytes::<true>),
            false => fitted(heights, (width, height), request).map(bytes::<false>),
        };
        let mut greys = greys.map_err(&in_failure)?;
        if let Some(valid) = &valid {
            for (g, _) in greys.iter_mut().zip(valid).filter(|(_, v)| !**v) {
                *g = 0;
                self.summary.missing += 1;
            }
        }
        let (greys, size) = match tile {
            true => (crate::light::tile_2x2(&greys, width, height).map_err(&in_failure)?, (2 * width, 2 * height)),
            false => (greys, (width, height)),
        };
        let Some(out) = out else {
            self.pixels = Some(greys);
            return Ok(());
        };
        self.prepare(&out, Place::Output)?;
        let mut files = std::mem::take(&mut self.files);
        let (encoding, tags) = (self.encoding, self.tiff_tags());
        write_to(out, &mut files, |w| io::write::encode_gray_tagged(&greys, size, &encoding, tags, w))
            .map_err(ConvertError::at(Place::Output))?;
        self.files = files;
        Ok(())
    }
}

impl Job<'_> {
    /// The curvature of the whole image ([`crate::fit::curvature`]),
    /// written as one channel: float as it is, 8 or 16 bits by
    /// [`crate::fit::quadratic::encode`] with `range` white.
    fn curvature_whole(
        &mut self,
        heights: &Samples,
        (width, height): (usize, usize),
        fit: &Options,
        (encoding, range): (Encoding, f64),
        out: Option<Output<'_>>,
    ) -> Result<(), ConvertError> {
        let in_failure = ConvertError::at(Place::Input);
        let Some(out) = out else {
            let problem = "nothing to write: no output given";
            return Err(ConvertError { place: Place::Output, error: Error::InvalidOption(problem.into()) });
        };
        let values = crate::fit::curvature_samples(heights, width, height, fit).map_err(&in_failure)?;
        self.summary.missing = values.iter().filter(|v| v.is_nan()).count();
        self.prepare(&out, Place::Output)?;
        let mut files = std::mem::take(&mut self.files);
        let tags = self.tiff_tags();
        let code = |max: u32| values.iter().map(move |&k| crate::fit::quadratic::encode(k, range, max));
        let on_out = ConvertError::at(Place::Output);
        match encoding {
            Encoding::Png(io::PngOptions { depth: io::PngDepth::Eight, .. })
            | Encoding::Tiff(io::encoding::TiffOptions { depth: io::encoding::TiffDepth::Eight, .. }) => {
                let codes: Vec<u8> = code(255).map(|c| c as u8).collect();
                write_to(out, &mut files, |w| {
                    io::write::encode_gray_tagged(&codes, (width, height), &encoding, tags, w)
                })
            }
            Encoding::Png(_)
            | Encoding::Tiff(io::encoding::TiffOptions { depth: io::encoding::TiffDepth::Sixteen, .. }) => {
                let codes: Vec<u16> = code(65535).map(|c| c as u16).collect();
                write_to(out, &mut files, |w| {
                    io::write::encode_gray_tagged(&codes, (width, height), &encoding, tags, w)
                })
            }
            Encoding::Exr(_) | Encoding::Tiff(_) => write_to(out, &mut files, |w| {
                io::write::encode_gray_tagged(&values, (width, height), &encoding, tags, w)
            }),
            Encoding::Texture(_) => {
                Err(Error::Unsupported("a curvature map is written as .png, .exr or .tif, not as a GPU texture".into()))
            }
        }
        .map_err(on_out)?;
        self.files = files;
        Ok(())
    }
}

impl Job<'_> {
    /// A slope or an aspect map of the whole image: its values made in
    /// the fit's loop ([`crate::units::Measure::with_texel`]),
    /// [`crate::units::NODATA`] at the holes, written as one float channel.
    fn terrain_whole(
        &mut self,
        heights: &Samples,
        (width, height): (usize, usize),
        fit: &Options,
        (measure, encoding): (crate::units::Measure, Encoding),
        out: Option<Output<'_>>,
    ) -> Result<(), ConvertError> {
        let in_failure = ConvertError::at(Place::Input);
        let Some(out) = out else {
            let problem = "nothing to write: no output given";
            return Err(ConvertError { place: Place::Output, error: Error::InvalidOption(problem.into()) });
        };
        let affine = self.georef.and_then(crate::io::Georef::affine);
        let mut valid = None;
        let whole = MeasureWhole { heights, size: (width, height), fit, affine, valid: &mut valid };
        let mut values = measure.with_texel(whole).map_err(&in_failure)?;
        if let Some(valid) = &valid {
            for (v, _) in values.iter_mut().zip(valid).filter(|(_, valid)| !**valid) {
                *v = crate::units::NODATA;
                self.summary.missing += 1;
            }
        }
        self.prepare(&out, Place::Output)?;
        let mut files = std::mem::take(&mut self.files);
        let tags = self.tiff_tags();
        write_to(out, &mut files, |w| io::write::encode_gray_tagged(&values, (width, height), &encoding, tags, w))
            .map_err(ConvertError::at(Place::Output))?;
        self.files = files;
        Ok(())
    }
}

/// [`Job::terrain_whole`]'s values: the measure's texels
/// ([`crate::units::Measure::with_texel`]) fitted over the whole image,
/// then the values of them; with holes, `valid` is set to which texels
/// have one.
struct MeasureWhole<'a> {
    heights: &'a Samples,
    size: (usize, usize),
    fit: &'a Options,
    affine: Option<crate::io::Affine>,
    valid: &'a mut Option<Vec<bool>>,
}

impl crate::units::WithTexel for MeasureWhole<'_> {
    type Output = crate::Result<Vec<f32>>;

    fn run<T: crate::units::MeasureTexel>(self) -> crate::Result<Vec<f32>> {
        let MeasureWhole { heights, size: (width, height), fit, affine, valid } = self;
        // The texels, which become the values in place, the validity (1
        // byte a texel); and the fit's own work, which grows with N.
        let texels = (width as u64).saturating_mul(height as u64);
        let holes = fit.nodata.is_some();
        let work = crate::fit::work_bytes(fit, (width, height), heights.unit(), holes, false)?;
        let per_texel = size_of::<T>() as u64 + 1;
        io::check_memory("measuring the slopes", texels.saturating_mul(per_texel).saturating_add(work))?;
        if holes {
            *valid = Some(zeroed::<bool>(heights.len())?);
        }
        let request = with_holes(crate::FitRequest::new(fit), None, valid.as_deref_mut()).on_map(affine.as_ref());
        let fitted: Vec<T> = fitted(heights, (width, height), request)?;
        // The same buffer, its texels' values.
        Ok(fitted.into_iter().map(T::value).collect())
    }
}

/// The file output at `path`.
fn file(path: &Path, create_folder: bool) -> Output<'_> {
    Output::File { path, create_folder }
}

/// The base roughness of a mip chain: the gray image at `path`, its
/// values in [0, 1] (integer samples over their maximum, floats as
/// stored), the size of the input.
///
/// Errors ([`Place::RoughnessBase`]): those of reading it; a size other
/// than `(width, height)`.
fn read_base(path: &Path, read: &io::ReadOptions, (width, height): (usize, usize)) -> Result<Vec<f32>, ConvertError> {
    let failure = ConvertError::at(Place::RoughnessBase);
    let raster = io::read_path(path, read).map_err(&failure)?;
    if (raster.width, raster.height) != (width, height) {
        return Err(failure(Error::InvalidOption(format!(
            "is {} × {}, the input {width} × {height}: a base roughness has the input's size",
            raster.width, raster.height
        ))));
    }
    raster.heights(None).map_err(&failure)
}
