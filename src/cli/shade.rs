//! `normalfit shade`: a normal map, or a height map through the fit, lit by
//! a directional light and written as a gray PNG, optionally tiled 2×2.

use std::collections::HashSet;
use std::io::Write;
use std::path::{Path, PathBuf};

use normalfit::io::{self, Channel, PngCompression, PngDepth, PngOptions, Raster, ReadOptions, SampleType};
use normalfit::shade::{Light, shade, tile_2x2};
use normalfit::tiling::{self, ImageKind, KindChoice, TilingOptions};
use normalfit::{Options, normals};

use super::args::{BorderArg, KindArg, ShadeArgs};
use super::fitting;
use super::input::{Input, InputIds, read_input, stdin_at_most_once};
use super::output::{self, Destination};
use super::report::Failure;
use super::tiling::{kind_of, rgb_planes};

/// What `shade` does with every input, decided once from the arguments.
struct Plan {
    /// The fit for height maps; the borders are settled per image.
    fit: Options,
    border: BorderArg,
    light: Light,
    tile: bool,
    kind: KindArg,
    channel: Option<Channel>,
    signed: bool,
    destination: Destination,
}

/// Shades every input; returns the failures (already reported).
pub fn run(args: ShadeArgs) -> Result<usize, Failure> {
    let fit = fitting::options(&args.fit)?;
    stdin_at_most_once(&args.inputs)?;
    let destination = Destination::new(args.output.as_deref(), &args.inputs)?;
    if let Destination::File(path) = &destination {
        let png = path.extension().is_none_or(|e| e.eq_ignore_ascii_case("png"));
        if !png {
            return Err(Failure::file(path, "shade writes PNG: name the output .png"));
        }
    }
    let plan = Plan {
        fit,
        border: args.fit.border,
        light: args.light.0,
        tile: args.tile,
        kind: args.kind,
        channel: args.channel.clone(),
        signed: args.signed,
        destination,
    };
    let ids = InputIds::of(&args.inputs);
    let mut written = HashSet::new();
    let mut failures = 0;
    for path in &args.inputs {
        let input = Input::from_arg(path);
        if let Err(f) = plan.shade_one(&input, &ids, &mut written) {
            f.report();
            failures += 1;
        }
    }
    Ok(failures)
}

impl Plan {
    fn shade_one(&self, input: &Input, ids: &InputIds, written: &mut HashSet<PathBuf>) -> Result<(), Failure> {
        let target = self.destination.path_for(input, &format!("{}_lit.png", input.stem()));
        if let Some(path) = &target {
            output::claim(path, input, ids, written)?;
        }
        let in_failure = |e: normalfit::Error| Failure::file(input.name(), e);
        let raster = read_input(input, &ReadOptions::default())?;
        let (w, h) = (raster.width, raster.height);
        let normals = match kind_of(&raster, self.kind, self.channel.as_ref()).map_err(in_failure)? {
            ImageKind::Normal => {
                self.decode_normals(&raster).map_err(|problem| Failure::file(input.name(), problem))?
            }
            ImageKind::Height => self.fit_normals(input, &raster).map_err(in_failure)?,
        };
        // `normals` are in the frame of --convention, which `shade` undoes,
        // so both conventions light the same on screen.
        let lit = shade(&normals, w, h, self.light, self.fit.convention).map_err(in_failure)?;
        let (lit, w, h) =
            if self.tile { (tile_2x2(&lit, w, h).map_err(in_failure)?, 2 * w, 2 * h) } else { (lit, w, h) };
        let encoding = PngOptions::new(PngDepth::Eight).with_compression(PngCompression::Default).into();
        match &target {
            Some(path) => io::write_file_atomically(path, |out| io::encode_gray(&lit, w, h, &encoding, out))
                .map_err(|e| Failure::file(path, e)),
            None => {
                let stdout_name = Path::new("<standard output>");
                let mut bytes = std::io::Cursor::new(Vec::new());
                io::encode_gray(&lit, w, h, &encoding, &mut bytes).map_err(|e| Failure::file(stdout_name, e))?;
                let bytes = bytes.into_inner();
                let mut stdout = std::io::stdout().lock();
                stdout.write_all(&bytes).and_then(|()| stdout.flush()).map_err(|e| Failure::file(stdout_name, e))
            }
        }
    }

    /// A normal map's stored colours back to normals: n = 2c − 1 per
    /// channel (c in [0, 1] as read), or n = c for `--signed` float maps.
    fn decode_normals(&self, raster: &Raster) -> Result<Vec<[f32; 3]>, String> {
        let planes = rgb_planes(raster).map_err(|e| e.to_string())?.ok_or("a normal map needs R, G and B channels")?;
        if self.signed && raster.sample != SampleType::Float {
            return Err("--signed is for float (EXR) normal maps; an integer image stores (n + 1)/2".into());
        }
        let decode = |c: f32| if self.signed { c } else { 2.0 * c - 1.0 };
        Ok((0..raster.width * raster.height).map(|k| planes.each_ref().map(|p| decode(p[k]))).collect())
    }

    /// A height map's normals, fitted with the command's options; `auto`
    /// borders and the warning about a wrap that draws a seam come from
    /// the tiling check, as in `convert`.
    fn fit_normals(&self, input: &Input, raster: &Raster) -> normalfit::Result<Vec<[f32; 3]>> {
        if self.signed {
            return Err(normalfit::Error::InvalidOption(
                "--signed is for normal maps, and this is a height map (use --kind normal if it is not)".into(),
            ));
        }
        let (w, h) = (raster.width, raster.height);
        let heights = raster.heights(self.channel.clone())?;
        let borders = self.border.choices();
        let report = borders
            .needs_check()
            .then(|| tiling::check(&[&heights], w, h, &TilingOptions::new().with_kind(KindChoice::Height)));
        if let Some(warning) = report.as_ref().and_then(|r| borders.seams(r)) {
            fitting::warn(&warning, input);
        }
        let fit = self.fit.clone().with_borders(borders.resolve(report.as_ref()));
        normals(&heights, w, h, &fit)
    }
}
