//! The `normalfit` command; see `cli/` for the program and `lib.rs` for the
//! library it drives.

mod cli;

fn main() -> std::process::ExitCode {
    cli::main()
}
