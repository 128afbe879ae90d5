//! `normalfit shade`: a normal map, or a height map through the fit, lit by
//! a directional light and written as a gray PNG, optionally tiled 2×2.
//! The picture is the library's ([`normalfit::shade::lit_view`]); here are
//! the output names, the rule that no output replaces an input, and the
//! messages.

use std::collections::HashSet;
use std::io::Write;
use std::path::{Path, PathBuf};

use normalfit::io::{self, ReadOptions};
use normalfit::shade::{LitOptions, lit_view};
use normalfit::tiling::KindChoice;

use super::args::{KindArg, ShadeArgs};
use super::fitting;
use super::input::{Input, InputIds, read_input, stdin_at_most_once};
use super::output::{self, Destination};
use super::report::Failure;

/// What `shade` does with every input, decided once from the arguments.
struct Plan {
    lit: LitOptions,
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
    let lit = LitOptions::new()
        .with_fit(fit)
        .with_borders(args.fit.border.choices())
        .with_light(args.light.0)
        .with_tile(args.tile)
        .with_kind(kind_choice(args.kind))
        .with_channel(args.channel.clone())
        .with_signed(args.signed);
    let plan = Plan { lit, destination };
    let ids = InputIds::of(&args.inputs);
    let mut written = HashSet::new();
    let mut failures = 0;
    for path in &args.inputs {
        let input = Input::from_arg(path);
        match plan.shade_one(&input, &ids, &mut written) {
            Ok(Shaded::Written) => {}
            // The reader of standard output went away: no error, as for
            // ripgrep and fd, and nothing more to write there.
            Ok(Shaded::PipeClosed) => break,
            Err(f) => {
                f.report();
                failures += 1;
            }
        }
    }
    Ok(failures)
}

/// `--kind` as the library's choice.
pub fn kind_choice(kind: KindArg) -> KindChoice {
    match kind {
        KindArg::Auto => KindChoice::Auto,
        KindArg::Height => KindChoice::Height,
        KindArg::Normal => KindChoice::Normal,
    }
}

/// What became of one input shaded without error.
enum Shaded {
    Written,
    PipeClosed,
}

impl Plan {
    fn shade_one(&self, input: &Input, ids: &InputIds, written: &mut HashSet<PathBuf>) -> Result<Shaded, Failure> {
        let target = self.destination.path_for(input, &format!("{}_lit.png", input.stem()));
        if let Some(path) = &target {
            output::claim(path, input, ids, written)?;
        }
        let raster = read_input(input, &ReadOptions::default())?;
        let view = lit_view(&raster, &self.lit).map_err(|e| Failure::file(input.name(), e))?;
        view.warnings.iter().for_each(|w| fitting::warn(w, input));
        match &target {
            Some(path) => {
                io::write_file_atomically(path, |out| view.encode(out)).map_err(|e| Failure::file(path, e))?;
            }
            None => {
                let stdout_name = Path::new("<standard output>");
                let mut bytes = std::io::Cursor::new(Vec::new());
                view.encode(&mut bytes).map_err(|e| Failure::file(stdout_name, e))?;
                let mut stdout = std::io::stdout().lock();
                match stdout.write_all(bytes.get_ref()).and_then(|()| stdout.flush()) {
                    Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => return Ok(Shaded::PipeClosed),
                    other => other.map_err(|e| Failure::file(stdout_name, e))?,
                }
            }
        }
        Ok(Shaded::Written)
    }
}
