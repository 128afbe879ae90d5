//! The command line as clap sees it. Nothing here computes: `convert.rs`,
//! `shade.rs` and `tiling.rs` turn these into the library's options.

use std::fmt;
use std::path::PathBuf;
use std::sync::OnceLock;

use clap::builder::{PossibleValue, PossibleValuesParser, TypedValueParser};
use clap::{Args, Parser, Subcommand, ValueEnum};
use clap_complete::Shell;
use normalfit::blend::{BlendOptions, Method};
use normalfit::convert::{BorderChoices, Conversion};
use normalfit::height::file::Holes;
use normalfit::height::{ConventionChoice, HeightOptions, Model};
use normalfit::io::{
    Alpha, ByteOrder, Channel, OutputChannels, OutputFormat, PackedElevation, PngCompression, RawOptions, ReadOptions,
    TextureCompression,
};
use normalfit::mips::MipChoice;
use normalfit::normal_map::KindChoice;
use normalfit::options::UnitsName;
use normalfit::shade::{Light, LitOptions};
use normalfit::tiling::TilingOptions;
use normalfit::{Borders, Convention, Fit, Options, Product, SlopeUnits, Weights};

/// Tangent-space normal maps from height maps, by least-squares plane fits;
/// and whether a texture tiles seamlessly.
#[derive(Parser, Debug)]
#[command(name = "normalfit", version, about, propagate_version = true)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Turn height maps into normal maps.
    Convert(ConvertArgs),
    /// Tell whether images tile seamlessly (exit 0: all tile, 1: a seam).
    Tiling(TilingArgs),
    /// Render normal maps, or height maps through the fit, lit by a
    /// directional light, to gray PNGs (optionally tiled 2×2).
    ///
    /// A height map goes through the same fit as `convert` (the fit options
    /// below). A normal map's colours c are read back as n = 2c − 1 (PNG,
    /// TIFF, …; EXR holding (n + 1)/2), or n = c with `--signed` (EXR holding
    /// n itself); --convention says which way its green points. Lambert
    /// shading with a little ambient light, so slopes turned away stay grey.
    Shade(ShadeArgs),
    /// Turn a normal map back into heights: the exact inverse of the fit
    /// (the heights whose fitted normals are closest, in least squares, to
    /// the map's slopes), or a generic integration for maps normalfit did
    /// not make.
    ///
    /// Give the fit options the normal map was made with (-n, --fit,
    /// --border, -s or --relief, --invert): `convert -s S` then `height -s
    /// S` returns the original heights up to a constant. The output is an
    /// EXR of float heights (channel Y, mean 0, units of the gain) or, named
    /// .png, a 16-bit gray PNG normalised to [0, 1] whose range is printed.
    Height(HeightArgs),
    /// Blend a detail normal map onto a base: rnm (Reoriented Normal
    /// Mapping, the default), whiteout, udn or linear (docs/blend.md).
    ///
    /// A detail smaller than the base is tiled (its sides must divide the
    /// base's). A detail of the other green convention than the base has its
    /// green flipped; the result is in the base's convention.
    Blend(BlendArgs),
    /// Check normal maps: lengths, negative z, a two-channel (RG) layout,
    /// the green convention (guessed from the map's curl), 8-bit banding and
    /// seams (exit 0: all clean, 1: a finding, 2: an error).
    Check(CheckArgs),
    /// Print a shell completion script to standard output.
    Completions(CompletionsArgs),
    /// Print the manual page (roff) to standard output, or write one page
    /// per command.
    Man(ManArgs),
}

/// How a height map becomes normals: the options `convert` and `shade`
/// share, flattened into both so that their help and defaults are one.
#[derive(Args, Debug)]
#[command(next_help_heading = "Fit options")]
pub struct FitArgs {
    /// Patch size N: fit a plane to the N×N texels around each texel (odd, ≥ 3).
    /// Larger patches smooth more; the cost does not grow with N.
    #[arg(short = 'n', long, value_name = "N", default_value_t = Options::DEFAULT_PATCH, value_parser = parse_patch)]
    pub patch: usize,

    /// Detail at several scales, in place of -n: patch sizes and weights
    /// `N:W,N:W,…` (e.g. 3:1,9:0.5,33:0.25); the normal of the weighted sum
    /// of the scales' slopes (docs/detail.md). Costs a fit per scale.
    #[arg(long, value_name = "N:W,…", value_parser = parse_detail, conflicts_with = "patch")]
    pub detail: Option<normalfit::Detail>,

    /// Height gain S: the [0, 1] height range spans S texel widths.
    #[arg(short, long, value_name = "S", default_value_t = Options::DEFAULT_SCALE, value_parser = parse_finite,
          conflicts_with = "relief")]
    pub scale: f64,

    /// Gain relative to the width: S = F × image width, so the look does not
    /// change with resolution.
    #[arg(long, value_name = "F", value_parser = parse_finite)]
    pub relief: Option<f64>,

    /// Heights are depths: negate the gain.
    #[arg(long)]
    pub invert: bool,

    /// Which least-squares plane: perpendicular distances (orthogonal) or
    /// vertical ones.
    #[arg(long, default_value_t = Options::default().fit, value_parser = named::<Fit>(Fit::ALL))]
    pub fit: Fit,

    /// How the fit weighs the patch's points: uniform (every point alike),
    /// or binomial (Pascal's row for N, 1 2 1 at N = 3: Horn's gradient,
    /// gdaldem's, with --fit vertical).
    #[arg(long, default_value_t = Options::default().weights, value_parser = named::<Weights>(Weights::ALL))]
    pub weights: Weights,

    /// Border mode, one for both axes or `X,Y`: wrap (tiles), clamp, mirror,
    /// or auto (wrap where the image tiles, mirror where it does not).
    #[arg(long, value_name = "MODE[,MODE]", default_value = default_borders(), value_parser = parse_borders)]
    pub border: BorderChoices,

    /// Which way the normal maps' green points: up (opengl: glTF, Blender,
    /// Unity) or down (directx: Unreal).
    #[arg(long, default_value_t = Options::default().convention, value_parser = named::<Convention>(Convention::ALL))]
    pub convention: Convention,
}

#[derive(Args, Debug)]
#[command(allow_negative_numbers = true)]
pub struct ConvertArgs {
    /// Height maps to convert (the formats read, from the library's
    /// registry; `-` reads standard input).
    #[arg(required = true, value_name = "INPUT", help = inputs_help("Height maps to convert"))]
    pub inputs: Vec<PathBuf>,

    /// Output file, or folder for many inputs; `-` writes standard output.
    /// Default: `<stem>_normal.<ext>` beside each input (standard output for
    /// standard input).
    #[arg(short, long, value_name = "OUTPUT")]
    pub output: Option<PathBuf>,

    /// Channel that holds the height: luma, r, g, b or a of a colour image
    /// (gray images use gray), or an OpenEXR channel by name (Z, height,
    /// diffuse.R). Default: gray; for EXR, Y, the only channel, else luma.
    #[arg(long, value_name = "C", value_parser = parse_channel)]
    pub channel: Option<Channel>,

    /// Bits per output channel: 8 or 16 for PNG, 16 (half) or 32 (float) for
    /// EXR, 8, 16 or 32 (float) for TIFF. Default: 16 for inputs of more
    /// than 8 bits, else 8; 32 for EXR.
    #[arg(long, value_name = "BITS", value_parser = parse_bits)]
    pub bits: Option<u8>,

    /// Output format; default: the output file's extension (.png, .exr, .tif,
    /// .dds, .ktx2), else the input's format (PNG for integer images, EXR
    /// for float ones). TIFF from a GeoTIFF is a GeoTIFF: its georeferencing
    /// tags copied. DDS and KTX2 are GPU textures: the mip chain with
    /// --mips, else level 0 alone.
    #[arg(long, value_parser = named::<OutputFormat>(OutputFormat::ALL))]
    pub format: Option<OutputFormat>,

    /// Write the normal's components in [−1, 1] instead of (n + 1)/2 (float
    /// outputs only: EXR, 32-bit TIFF).
    #[arg(long)]
    pub signed: bool,

    /// PNG output: fast (one cheap filter for every row; rows that deflate
    /// would shrink by less than a tenth, as 16-bit ones, are stored) or
    /// small (each row's best filter, every row deflated unless that makes
    /// it larger: about 12 % smaller at 8 bits, a little slower).
    #[arg(long, default_value_t = Conversion::default().compression,
          value_parser = named::<PngCompression>(PngCompression::NAMED))]
    pub compression: PngCompression,

    /// What to make: normals, or curvature (the mean curvature of the
    /// quadratic fitted over each patch, convex positive, in 1/texel or,
    /// with --units map, 1/map unit: written as it is in EXR and float
    /// TIFF, mapped to gray in 8- and 16-bit outputs, flat at mid-gray;
    /// docs/curvature.md). Curvature streams into EXR and PNG files; into
    /// TIFF or a pipe it reads the image whole. slope, aspect (float32 TIFF
    /// or EXR, nodata −9999) and hillshade (8-bit TIFF or PNG, 1 to 255,
    /// nodata 0) as gdaldem makes them, from the plane fitted over each
    /// patch (docs/products.md).
    #[arg(long, default_value_t = Product::default(), value_parser = named::<Product>(Product::ALL))]
    pub product: Product,

    /// The curvature that maps to white in an 8- or 16-bit curvature map
    /// (minus it to black; beyond, clipped). Default: 0.1.
    #[arg(long, value_name = "R", value_parser = parse_curvature_range)]
    pub curvature_range: Option<f64>,

    #[command(flatten)]
    pub read: ReadArgs,

    #[command(flatten)]
    pub mips: MipArgs,

    // The groups with a help heading come after the options without one,
    // which a heading would otherwise cover.
    #[command(flatten)]
    pub channels: ChannelsArgs,

    #[command(flatten)]
    pub terrain: TerrainArgs,

    #[command(flatten)]
    pub products: ProductArgs,

    #[command(flatten)]
    pub holes: HolesArgs,

    #[command(flatten)]
    pub units: UnitsArgs,

    /// Appended to each input's stem to name its output. Files whose stem
    /// already ends in it (or in `_residual`) are taken for outputs and
    /// skipped when folders are searched.
    #[arg(long, value_name = "TEXT", default_value = "_normal", value_parser = parse_suffix,
          help_heading = "Batches")]
    pub suffix: String,

    #[command(flatten)]
    pub batch: BatchArgs,

    #[command(flatten)]
    pub fit: FitArgs,
}

/// Slope, aspect and hillshade maps (`--product`, docs/products.md).
#[derive(Args, Debug)]
#[command(next_help_heading = "Slope, aspect, hillshade")]
pub struct ProductArgs {
    /// A slope map's units: degrees (0 to 90), or percent (100 · rise over
    /// run, as `gdaldem slope -p`).
    #[arg(long, default_value_t = Conversion::default().slope_units,
          value_parser = named::<SlopeUnits>(SlopeUnits::ALL))]
    pub slope_units: SlopeUnits,

    /// An aspect map's flat texels are 0, not −9999 (gdaldem's
    /// `-zero_for_flat`).
    #[arg(long)]
    pub zero_for_flat: bool,

    /// A hillshade's sun: its azimuth in degrees clockwise from north, as
    /// `gdaldem hillshade -az`. The vertical exaggeration (gdaldem's -z)
    /// is the gain, -s.
    #[arg(long, value_name = "DEGREES", allow_hyphen_values = true,
          default_value_t = Conversion::default().sun.azimuth_deg)]
    pub azimuth: f64,

    /// A hillshade's sun: its altitude in degrees above the horizon, as
    /// `gdaldem hillshade -alt`.
    #[arg(long, value_name = "DEGREES", default_value_t = Conversion::default().sun.altitude_deg)]
    pub altitude: f64,
}

/// Mip chains and GPU textures (docs/mips.md).
#[derive(Args, Debug)]
#[command(next_help_heading = "Mip chains")]
pub struct MipArgs {
    /// Write every mip level down to 1 × 1: fit (each level the plane fit
    /// of the heights box-filtered to its size; height maps only) or
    /// average (the renormalised mean of the finer level's normals; normal
    /// maps). Alone, or auto: fit for a height map, average for a normal
    /// map. A .dds or .ktx2 output holds the chain; an image output holds
    /// level 0 and level k ≥ 1 goes to `<stem>_mip<k>.<ext>` beside it.
    #[arg(long, value_name = "WAY", num_args = 0..=1, default_missing_value = "auto",
          value_parser = named::<MipChoice>(MipChoice::ALL))]
    pub mips: Option<MipChoice>,

    /// A .dds or .ktx2 output's normals: bc5 (x and y; the default), bc7
    /// (x, y, z; builds with the bc7 feature) or none (RGBA8, RG8 with
    /// --channels rg, half floats with --bits 16).
    #[arg(long, value_parser = named::<TextureCompression>(TextureCompression::ALL))]
    pub compress: Option<TextureCompression>,

    /// With --mips, a roughness chain too: `<stem>_roughness.<ext>` (BC4,
    /// R8 or R16F in a texture; gray in an image, its levels named as the
    /// normals'), each texel's perceptual roughness from what the level's
    /// normals lose (Toksvig): α² = α_base² + (1 − |n̄|)/|n̄|, r = √α.
    #[arg(long)]
    pub roughness: bool,

    /// The base perceptual roughness the chain adds to: a gray image of the
    /// input's size (8 or 16 bits, or float, in [0, 1]). Implies
    /// --roughness.
    #[arg(long, value_name = "FILE")]
    pub roughness_base: Option<PathBuf>,
}

/// What the output holds besides the normal, for pipelines.
#[derive(Args, Debug)]
#[command(next_help_heading = "Channels")]
pub struct ChannelsArgs {
    /// Alpha channel: none (RGB), height (the input height, for parallax
    /// mapping: integer inputs in [0, 1], float ones as stored, clamped to
    /// [0, 1] in PNG), or one (opaque).
    #[arg(long, default_value_t = Alpha::default(), value_parser = named::<Alpha>(Alpha::ALL))]
    pub alpha: Alpha,

    /// rgb, or rg for two-channel (BC5) pipelines whose shader rebuilds z:
    /// EXR gets channels R and G only; PNG stays RGB with B = 0, which BC5
    /// encoders ignore.
    #[arg(long, default_value_t = OutputChannels::default(), value_parser = named::<OutputChannels>(OutputChannels::ALL))]
    pub channels: OutputChannels,

    /// Also write the fit's residual: per texel, the root-mean-square
    /// distance of the patch's points from the fitted plane (perpendicular
    /// for the orthogonal fit, vertical for the vertical one), divided by
    /// the gain S, so in height units (integer inputs: 1 = full range).
    /// Planes give 0; pits, bumps and grain give more. 16-bit gray PNG
    /// (65535 · value, clamped to 1) or 32-bit float EXR (channel Y), by the
    /// file's extension. With many inputs, a folder of
    /// `<stem>_residual.<ext>`, ext as the normal map's.
    #[arg(long, value_name = "FILE")]
    pub residual: Option<PathBuf>,
}

/// Many files at once: the options of every command that takes many files
/// (the batch driver, `batch.rs`).
#[derive(Args, Debug)]
#[command(next_help_heading = "Batches")]
pub struct BatchArgs {
    /// Folders named as inputs are searched in their subfolders too
    /// (symbolic links to folders are not followed).
    #[arg(short, long)]
    pub recursive: bool,

    /// Files done at once. Each file's fit already uses every core; more
    /// jobs overlap the decoding, compressing and syncing of small files,
    /// which run on one thread. Default: twice the cores, at most 8; one
    /// under a memory limit (`ulimit -v`), where each file is checked
    /// against the memory left when it starts.
    #[arg(short, long, value_name = "N", value_parser = clap::value_parser!(u16).range(1..=256))]
    pub jobs: Option<u16>,

    /// When an output exists already: always replace it, never (skip the
    /// input's output), or only when it is older than the input.
    #[arg(long, value_enum, default_value_t = OverwriteArg::Always)]
    pub overwrite: OverwriteArg,

    /// No progress bar, no summary line, no warnings: errors only.
    #[arg(short, long)]
    pub quiet: bool,
}

#[derive(ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum OverwriteArg {
    Always,
    Never,
    Older,
}

#[derive(Args, Debug)]
#[command(allow_negative_numbers = true)]
pub struct ShadeArgs {
    /// Normal maps or height maps (the formats read, from the library's
    /// registry; `-` reads standard input).
    #[arg(required = true, value_name = "INPUT", help = inputs_help("Normal maps or height maps"))]
    pub inputs: Vec<PathBuf>,

    /// Output PNG, or TIFF (.tif: a GeoTIFF from a GeoTIFF, nodata 0, as
    /// gdaldem writes), or folder for many inputs (or folders of them, whose
    /// layout it keeps); `-` writes standard output (PNG). Default:
    /// `<stem>_lit.png` beside each input (standard output for standard
    /// input). Files named `*_lit.*` are skipped when folders are searched.
    #[arg(short, long, value_name = "OUTPUT")]
    pub output: Option<PathBuf>,

    /// Where the light comes from, in degrees: the azimuth counter-clockwise
    /// from the image's right (0 right, 90 top, 135 top-left, 180 left), and
    /// the elevation above the surface (90 overhead, small values rake).
    /// The texture view, with a little ambient light. Default: 135,35, for
    /// inputs without georeferencing (a GeoTIFF with a transform gets the
    /// sun: --azimuth, --altitude).
    #[arg(long, value_name = "AZIMUTH,ELEVATION", value_parser = parse_light, allow_hyphen_values = true,
          conflicts_with_all = ["azimuth", "altitude"])]
    pub light: Option<LightArg>,

    /// The sun's azimuth in degrees clockwise from north, as `gdaldem
    /// hillshade -az` (315 north-west, the default): a hillshade in GIS
    /// convention, 1 (shadow) to 255 like gdaldem's, north from the
    /// GeoTIFF's transform (up the image without one). Georeferenced inputs
    /// get it by default; giving it (or --altitude) lights every input so.
    #[arg(long, value_name = "DEGREES", allow_hyphen_values = true)]
    pub azimuth: Option<f64>,

    /// The sun's altitude in degrees above the horizon, as `gdaldem
    /// hillshade -alt` (default 45).
    #[arg(long, value_name = "DEGREES")]
    pub altitude: Option<f64>,

    /// Repeat the lit view 2×2, so the wrap seams cross the middle.
    #[arg(long)]
    pub tile: bool,

    /// What the inputs hold; auto decides from the pixels (as `tiling` does).
    #[arg(long, default_value_t = LitOptions::default().kind, value_parser = named::<KindChoice>(KindChoice::ALL))]
    pub kind: KindChoice,

    /// Channel of a height map that holds the height: luma, r, g, b, a, or
    /// an OpenEXR channel by name.
    #[arg(long, value_name = "C", value_parser = parse_channel)]
    pub channel: Option<Channel>,

    /// Float (EXR) normal maps hold the normal n in [−1, 1], not (n + 1)/2.
    #[arg(long)]
    pub signed: bool,

    // The groups with a help heading come last: a heading would otherwise
    // cover the options after it.
    #[command(flatten)]
    pub terrain: TerrainArgs,

    #[command(flatten)]
    pub units: UnitsArgs,

    #[command(flatten)]
    pub holes: HolesArgs,

    #[command(flatten)]
    pub batch: BatchArgs,

    #[command(flatten)]
    pub fit: FitArgs,
}

#[derive(Args, Debug)]
#[command(allow_negative_numbers = true)]
pub struct HeightArgs {
    /// Normal maps (the formats read, from the library's registry): R, G
    /// and B hold (n + 1)/2, or n for a float map with --signed.
    #[arg(required = true, value_name = "INPUT", help = inputs_help("Normal maps to turn into heights"))]
    pub inputs: Vec<PathBuf>,

    /// Output file (.exr: float heights, the default; .tif: float heights;
    /// .png: 16-bit, normalised to [0, 1]), or folder for many inputs (or folders of
    /// them, whose layout it keeps); `-` writes standard output. Default:
    /// `<stem>_height.exr` beside each input (standard output for standard
    /// input). Files named `*_height.*` are skipped when folders are
    /// searched.
    #[arg(short, long, value_name = "OUTPUT")]
    pub output: Option<PathBuf>,

    /// Output format when the output's name does not say (standard output,
    /// names made from the inputs'). Default: exr.
    #[arg(long, value_parser = named::<OutputFormat>(OutputFormat::ALL))]
    pub format: Option<OutputFormat>,

    /// exact: the inverse of normalfit's fit (its N, fit and borders), for
    /// maps normalfit made; generic: Frankot–Chellappa integration, for
    /// maps of other origin (bakes, scans) or unknown N.
    #[arg(long, default_value_t = HeightOptions::default().model, value_parser = named::<Model>(Model::ALL))]
    pub model: Model,

    /// Float (EXR) normal maps hold n in [−1, 1], not (n + 1)/2.
    #[arg(long)]
    pub signed: bool,

    /// Patch size N the normal map was fitted with (odd, ≥ 3).
    #[arg(short = 'n', long, value_name = "N", default_value_t = Options::DEFAULT_PATCH, value_parser = parse_patch)]
    pub patch: usize,

    /// Height gain S the normal map was made with; heights come back in its
    /// units.
    #[arg(short, long, value_name = "S", default_value_t = Options::DEFAULT_SCALE, value_parser = parse_finite,
          conflicts_with = "relief")]
    pub scale: f64,

    /// Gain relative to the width: S = F × image width.
    #[arg(long, value_name = "F", value_parser = parse_finite)]
    pub relief: Option<f64>,

    /// The gain was negated (heights were depths).
    #[arg(long)]
    pub invert: bool,

    /// The fit the normal map was made with.
    #[arg(long, default_value_t = Options::default().fit, value_parser = named::<Fit>(Fit::ALL))]
    pub fit: Fit,

    /// Border mode the normal map was made with, one for both axes or `X,Y`:
    /// wrap, clamp or mirror.
    #[arg(long, value_name = "MODE[,MODE]", default_value = default_borders(), value_parser = parse_fixed_borders)]
    pub border: Borders,

    /// Which way the map's green points: opengl (up), directx (down), or
    /// auto (the one whose slopes are more nearly integrable; printed).
    #[arg(long, default_value_t = HeightOptions::default().convention(),
          value_parser = named::<ConventionChoice>(ConventionChoice::ALL))]
    pub convention: ConventionChoice,

    /// Texels whose heights are not asked for, NaN (alpha 0 in a PNG) in
    /// the output: auto, those convert wrote for a nodata value (an alpha of 0 and
    /// full only: its 0s; NaN normals); none; or a mask image of the map's
    /// size (alpha 0, else a first channel not 0, is a hole).
    #[arg(long, value_name = "MASK|auto|none", default_value = "auto", value_parser = parse_holes)]
    pub holes: Holes,

    #[command(flatten)]
    pub read: ReadArgs,

    // The groups with a help heading come last: a heading would otherwise
    // cover the options after it.
    #[command(flatten)]
    pub batch: BatchArgs,
}

#[derive(Args, Debug)]
pub struct BlendArgs {
    /// The base normal map (`-` reads standard input).
    #[arg(value_name = "BASE")]
    pub base: PathBuf,

    /// The detail normal map, as large as the base or tiled over it.
    #[arg(value_name = "DETAIL")]
    pub detail: PathBuf,

    /// Output file (.png, .exr, .tif); `-` writes standard output (--format
    /// says which, default the base's).
    #[arg(short, long, value_name = "OUTPUT", required = true)]
    pub output: PathBuf,

    /// The formula.
    #[arg(long, default_value_t = BlendOptions::default().method, value_parser = named::<Method>(Method::ALL))]
    pub method: Method,

    /// Factor on the detail's slopes (0 leaves the base).
    #[arg(long, value_name = "F", default_value_t = BlendOptions::default().strength, value_parser = parse_finite)]
    pub strength: f64,

    /// The inputs' green convention: opengl, directx, or auto (each map's
    /// guessed from its curl).
    #[arg(long, default_value_t = ConventionChoice::Auto,
          value_parser = named::<ConventionChoice>(ConventionChoice::ALL))]
    pub convention: ConventionChoice,

    /// The detail's convention, when it is not --convention's.
    #[arg(long, value_name = "CONVENTION", value_parser = named::<ConventionChoice>(ConventionChoice::ALL))]
    pub detail_convention: Option<ConventionChoice>,

    /// Output bits: 8 or 16 (PNG, TIFF), 16 or 32 (EXR). Default: 16 when
    /// the base has more than 8 bits, else 8; 32 for EXR.
    #[arg(long, value_name = "BITS", value_parser = parse_bits)]
    pub bits: Option<u8>,

    /// Output format when the output's name does not say.
    #[arg(long, value_parser = named::<OutputFormat>(OutputFormat::ALL))]
    pub format: Option<OutputFormat>,

    /// Float (EXR) inputs hold n in [−1, 1], not (n + 1)/2.
    #[arg(long)]
    pub signed: bool,

    #[command(flatten)]
    pub read: ReadArgs,
}

#[derive(Args, Debug)]
pub struct CheckArgs {
    /// Normal maps to check (`-` reads standard input).
    #[arg(required = true, value_name = "MAP", help = inputs_help("Normal maps to check"))]
    pub inputs: Vec<PathBuf>,

    /// One JSON object per map, one per line.
    #[arg(long)]
    pub json: bool,

    /// Write each map repaired: renormalised, z rebuilt for two-channel
    /// maps, green flipped with --to. A file, or a folder for many maps
    /// (`<stem>_fixed.<ext>`).
    #[arg(long, value_name = "OUT")]
    pub fix: Option<PathBuf>,

    /// With --fix: the convention to write (the map's own is stated with
    /// --convention or guessed confidently).
    #[arg(long, value_name = "CONVENTION", requires = "fix", value_parser = named::<Convention>(Convention::ALL))]
    pub to: Option<Convention>,

    /// The convention the maps should be in (a confident guess of the
    /// other is a finding); auto expects none.
    #[arg(long, default_value_t = ConventionChoice::Auto,
          value_parser = named::<ConventionChoice>(ConventionChoice::ALL))]
    pub convention: ConventionChoice,

    /// Seam score above which an axis has a visible seam.
    #[arg(long, value_name = "T", value_parser = parse_finite)]
    pub threshold: Option<f64>,

    /// Float (EXR) maps hold n in [−1, 1], not (n + 1)/2.
    #[arg(long)]
    pub signed: bool,

    #[command(flatten)]
    pub read: ReadArgs,

    #[command(flatten)]
    pub batch: BatchArgs,
}

#[derive(Args, Debug)]
pub struct CompletionsArgs {
    /// The shell to complete for.
    #[arg(value_enum)]
    pub shell: Shell,
}

#[derive(Args, Debug)]
pub struct ManArgs {
    /// Write one page per command into this folder (normalfit.1,
    /// normalfit-convert.1, …) instead of the whole manual to standard output.
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
}

#[derive(Args, Debug)]
#[command(allow_negative_numbers = true)]
pub struct TilingArgs {
    /// Images to check (height or normal maps, in the formats read, from
    /// the library's registry; `-` reads standard input).
    #[arg(required = true, value_name = "IMAGE", help = inputs_help("Images to check (height or normal maps)"))]
    pub inputs: Vec<PathBuf>,

    /// One JSON object per image, one per line.
    #[arg(long)]
    pub json: bool,

    /// Score above which an axis has a visible seam.
    #[arg(long, value_name = "T", value_parser = parse_finite)]
    pub threshold: Option<f64>,

    /// What the images hold; auto decides from the pixels.
    #[arg(long, default_value_t = TilingOptions::default().kind, value_parser = named::<KindChoice>(KindChoice::ALL))]
    pub kind: KindChoice,

    /// Channel of a height map that holds the height: luma, r, g, b, a, or
    /// an OpenEXR channel by name.
    #[arg(long, value_name = "C", value_parser = parse_channel)]
    pub channel: Option<Channel>,

    /// Write the image shifted by half its width and height, so both wrap
    /// seams cross the middle (PNG; for many images, a folder of
    /// `<stem>_preview.png`, keeping the layout of folders named as inputs).
    #[arg(long, value_name = "FILE")]
    pub preview: Option<PathBuf>,

    /// Height maps: write the lit view of their normal map (fitted with
    /// wrap), shifted the same way, where slope seams show (for many
    /// images, a folder of `<stem>_preview_lit.png`).
    #[arg(long, value_name = "FILE")]
    pub preview_lit: Option<PathBuf>,

    #[command(flatten)]
    pub read: ReadArgs,

    #[command(flatten)]
    pub holes: HolesArgs,

    #[command(flatten)]
    pub terrain: TerrainArgs,

    #[command(flatten)]
    pub batch: BatchArgs,
}

/// How terrain inputs are read: a GeoTIFF's band, a RAW heightmap's
/// layout, heights packed in RGB tiles (docs/terrain.md). Every rule is
/// the library's ([`ReadOptions`]); these only carry the values.
#[derive(Args, Debug)]
#[command(next_help_heading = "Terrain")]
pub struct TerrainArgs {
    /// TIFF: read band K (1-based, as GDAL counts) of a multi-band file,
    /// whatever its sample type. Default: the colour channels of an RGB
    /// TIFF, the first band of other multi-band files.
    #[arg(long, value_name = "K", value_parser = clap::value_parser!(u32).range(1..))]
    pub band: Option<u32>,

    /// RAW heightmaps (.raw, .r16, .r8): width and height. Default: a
    /// square found from the file's length (n² bytes for 8 bits, 2·n² for
    /// 16). Given, it also reads standard input and files whose extension
    /// names no format as RAW.
    #[arg(long, value_name = "WxH", value_parser = parse_raw_size)]
    pub size: Option<(usize, usize)>,

    /// RAW heightmaps: the byte order of 16-bit samples (little: Unity's
    /// Windows order and Unreal's .r16; big: Unity's Mac order). Given, it
    /// also reads standard input as RAW, as --size does.
    #[arg(long, value_name = "ORDER", value_parser = named::<ByteOrder>(ByteOrder::ALL))]
    pub byte_order: Option<ByteOrder>,

    /// Heights packed in 8-bit RGB tiles (PNG or WebP), unpacked to float
    /// metres: terrain-rgb (Mapbox: −10000 + (R·65536 + G·256 + B)·0.1) or
    /// terrarium (R·256 + G + B/256 − 32768).
    #[arg(long, value_name = "PACKING", value_parser = named::<PackedElevation>(PackedElevation::ALL))]
    pub decode: Option<PackedElevation>,
}

impl TerrainArgs {
    /// `opts` with these options applied.
    pub fn apply(&self, mut opts: ReadOptions) -> ReadOptions {
        if let Some(band) = self.band {
            opts = opts.with_band(band);
        }
        if let Some(raw) = RawOptions::given(self.size, self.byte_order) {
            opts = opts.with_raw(raw);
        }
        if let Some(packing) = self.decode {
            opts = opts.with_decode(packing);
        }
        opts
    }
}

/// Holes (docs/terrain.md, "Holes"): `convert`, `shade` and `tiling`
/// (whose seam check skips them).
#[derive(Args, Debug)]
#[command(next_help_heading = "Terrain")]
pub struct HolesArgs {
    /// Texels whose stored value is V (a 16-bit PNG's integer, a DEM's
    /// metres), and NaN or infinite ones, are holes: each patch is fitted
    /// to its valid points, and a texel that is a hole or whose points make
    /// no plane is missing (alpha 0; grey 0 in `shade`). Default: a
    /// GeoTIFF's GDAL_NODATA tag; `nan` marks only NaN and infinities;
    /// `none` ignores the tag (every value is a height). Without a value, a
    /// NaN height is an error.
    #[arg(long, value_name = "V|none", value_parser = parse_nodata, allow_hyphen_values = true)]
    pub nodata: Option<NodataArg>,
}

/// What `--nodata` says.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum NodataArg {
    /// This stored value marks holes.
    Value(f64),
    /// No value does, not even the file's tag.
    None,
}

impl HolesArgs {
    /// The fit's nodata value, if one is given.
    pub fn value(&self) -> Option<f64> {
        match self.nodata {
            Some(NodataArg::Value(v)) => Some(v),
            _ => None,
        }
    }

    /// `opts` reading a GeoTIFF's GDAL_NODATA tag, unless `none` is given.
    pub fn apply(&self, opts: ReadOptions) -> ReadOptions {
        opts.with_nodata_tag(self.nodata != Some(NodataArg::None))
    }
}

/// `--nodata V`: a number, or nan, inf, -inf; or none.
fn parse_nodata(s: &str) -> Result<NodataArg, String> {
    let s = s.trim();
    if s.eq_ignore_ascii_case("none") {
        return Ok(NodataArg::None);
    }
    s.parse::<f64>().map(NodataArg::Value).map_err(|_| format!("'{s}' is not a number (or nan, or none)"))
}

/// Fits in real-world units (docs/terrain.md), for `convert` and `shade`.
/// The rules are the library's ([`normalfit::units::MapSpacing`]).
#[derive(Args, Debug)]
#[command(next_help_heading = "Terrain")]
pub struct UnitsArgs {
    /// Units of the fit: texels (heights in [0, 1] for integer files, texels
    /// one unit apart: the gain S) or map (heights as stored, a DEM's
    /// metres, texels as far apart as the GeoTIFF's pixel size says, in
    /// metres at each row's latitude for degrees: a texel's slope is the
    /// terrain's, times S).
    #[arg(long, default_value_t = UnitsName::default(), value_parser = named::<UnitsName>(UnitsName::ALL))]
    pub units: UnitsName,

    /// Map units with this pixel size, X or X,Y (column to column, row to
    /// row) in the heights' unit, for files without georeferencing (PNG,
    /// RAW) or to override it. Implies --units map.
    #[arg(long, value_name = "X[,Y]", value_parser = parse_pixel_size)]
    pub pixel_size: Option<[f64; 2]>,
}

/// `--pixel-size X[,Y]`, as the library parses it.
fn parse_pixel_size(s: &str) -> Result<[f64; 2], String> {
    normalfit::units::parse_pixel_size(s).map_err(|e| library_message(&e))
}

/// `--size WxH`, as the library parses and checks it.
fn parse_raw_size(s: &str) -> Result<(usize, usize), String> {
    normalfit::io::parse_size(s).map_err(|e| library_message(&e))
}

/// How inputs are read: the size limit and, for OpenEXR, the layer.
#[derive(Args, Debug)]
pub struct ReadArgs {
    /// Refuse images of more than N texels (width × height), checked from
    /// the file's header before any pixel is decoded.
    #[arg(long, value_name = "N", default_value_t = ReadOptions::default().max_texels, value_parser = parse_max_texels)]
    pub max_texels: u64,

    /// OpenEXR: read the layer NAME, a part of that name or the channels
    /// NAME.* (default: the first part, all its channels).
    #[arg(long, value_name = "NAME")]
    pub layer: Option<String>,
}

impl ReadArgs {
    pub fn options(&self) -> ReadOptions {
        let opts = ReadOptions::default().with_max_texels(self.max_texels);
        match &self.layer {
            Some(name) => opts.with_layer(name.clone()),
            None => opts,
        }
    }
}

/// `-n N`, as the library parses and checks it.
fn parse_patch(s: &str) -> Result<usize, String> {
    normalfit::options::parse_patch(s).map_err(|e| library_message(&e))
}

/// `--curvature-range R`, as the library checks it.
fn parse_curvature_range(s: &str) -> Result<f64, String> {
    let v = s.trim().parse::<f64>().map_err(|_| format!("expected a number, got '{s}'"))?;
    normalfit::fit::quadratic::validate_range(v).map_err(|e| library_message(&e))
}

/// `--detail N:W,…`, as the library parses and checks it.
fn parse_detail(s: &str) -> Result<normalfit::Detail, String> {
    s.parse().map_err(|e| library_message(&e))
}

fn parse_suffix(s: &str) -> Result<String, String> {
    if s.contains(['/', '\\', '\0']) {
        return Err(format!("the suffix is part of a file name: no '/', '\\' or NUL, got '{s}'"));
    }
    Ok(s.to_string())
}

/// `--max-texels`: a whole number the library accepts as a limit.
fn parse_max_texels(s: &str) -> Result<u64, String> {
    let accepted = |&n: &u64| ReadOptions::default().with_max_texels(n).validate().is_ok();
    s.parse::<u64>()
        .ok()
        .filter(accepted)
        .ok_or_else(|| format!("--max-texels must be a whole number of texels, at least 1, got '{s}'"))
}

fn parse_bits(s: &str) -> Result<u8, String> {
    match s {
        "8" => Ok(8),
        "16" => Ok(16),
        "32" => Ok(32),
        _ => Err(format!("bits must be 8, 16 or 32, got '{s}'")),
    }
}

/// `--channel`: a keyword or an EXR channel's name, as the library takes
/// it (resolved per file: exact name first, then the keywords in any case).
fn parse_channel(s: &str) -> Result<Channel, String> {
    Channel::named(s).map_err(|e| library_message(&e))
}

fn parse_finite(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        _ => Err(format!("expected a finite number, got '{s}'")),
    }
}

/// The fit's default borders as `--border` spells them ("wrap").
fn default_borders() -> &'static str {
    static NAME: OnceLock<String> = OnceLock::new();
    NAME.get_or_init(|| Options::default().borders.to_string())
}

/// `--border` of `height`: fixed modes only (the map was made with them).
/// `--holes`: the library's words (auto, none) or a mask's path.
fn parse_holes(s: &str) -> Result<Holes, String> {
    s.parse::<Holes>().map_err(|e| e.to_string())
}

fn parse_fixed_borders(s: &str) -> Result<Borders, String> {
    parse_borders(s)?.fixed().map_err(|_| {
        format!("--border of a normal map names the modes it was made with (wrap, clamp, mirror), got '{s}'")
    })
}

/// `--border`: the library's rule (one mode, or x then y; `auto`).
fn parse_borders(s: &str) -> Result<BorderChoices, String> {
    s.parse().map_err(|e: normalfit::Error| library_message(&e))
}

/// A library value by its name: clap lists the names (help, completions)
/// and the library parses them.
fn named<T>(all: &'static [T]) -> impl TypedValueParser<Value = T>
where
    T: Copy + Send + Sync + 'static + std::str::FromStr<Err = normalfit::Error> + NamedValue,
{
    let values = all.iter().map(|v| PossibleValue::new(v.name()).aliases(v.aliases().iter().copied()));
    PossibleValuesParser::new(values.collect::<Vec<_>>()).try_map(|s| s.parse::<T>())
}

/// What [`named`] needs of a library enum.
trait NamedValue {
    fn name(self) -> &'static str;
    fn aliases(self) -> &'static [&'static str];
}

/// [`NamedValue`] for library enums that name their values.
macro_rules! named_value {
    ($($t:ty),+) => {
        $(impl NamedValue for $t {
            fn name(self) -> &'static str {
                <$t>::name(self)
            }
            fn aliases(self) -> &'static [&'static str] {
                <$t>::aliases(self)
            }
        })+
    };
}

named_value!(
    Product,
    SlopeUnits,
    Method,
    MipChoice,
    TextureCompression,
    Fit,
    Weights,
    UnitsName,
    Convention,
    OutputFormat,
    PngCompression,
    Alpha,
    OutputChannels,
    KindChoice,
    Model,
    ConventionChoice,
    ByteOrder,
    PackedElevation
);

/// A library error's message without its kind ("invalid option: ").
pub fn library_message(e: &normalfit::Error) -> String {
    match e {
        normalfit::Error::InvalidOption(m) => m.clone(),
        other => other.to_string(),
    }
}

/// `--light AZIMUTH,ELEVATION`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightArg(pub Light);

impl fmt::Display for LightArg {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{},{}", self.0.azimuth_deg, self.0.elevation_deg)
    }
}

fn parse_light(s: &str) -> Result<LightArg, String> {
    let usage = || format!("--light takes AZIMUTH,ELEVATION in degrees, such as 135,35; got '{s}'");
    let (azimuth, elevation) = s.split_once(',').ok_or_else(usage)?;
    let number = |v: &str| v.trim().parse::<f64>().ok().filter(|v| v.is_finite()).ok_or_else(usage);
    let light = Light::new(number(azimuth)?, number(elevation)?).map_err(|e| library_message(&e))?;
    Ok(LightArg(light))
}

/// The help of a command's inputs: what they are, then the formats the
/// library reads (its registry, so help and reader never disagree).
fn inputs_help(what: &str) -> String {
    format!("{what}: {}; `-` reads standard input", normalfit::io::read::formats::names())
}
