//! `penumbra`: parses the command line and hands over to the viewer or a
//! command.

use clap::Parser;
use penumbra::cli::{self, Cli, CliError, Command};

#[global_allocator]
static ALLOCATOR: cli::out_of_memory::EndWhenExhausted = cli::out_of_memory::EndWhenExhausted;

fn main() {
    penumbra::render::memory::share_one_arena_under_address_limit();
    // rayon's global pool starts now, while the address space has room:
    // started on its first use, late in a command under `ulimit -v`, a
    // thread that could not start panicked.
    if let Err(e) = rayon::ThreadPoolBuilder::new().build_global() {
        cli::print_stderr(format_args!(
            "penumbra: cannot start the worker threads: {e}"
        ));
        std::process::exit(1);
    }
    let cli = Cli::parse();
    let result = match cli.command.unwrap_or(Command::View(cli.view)) {
        Command::View(args) => penumbra::app::run(&args).map_err(CliError::input),
        Command::Render(args) => cli::render(&args),
        Command::Compare(args) => cli::compare(&args),
        Command::Merge(args) => cli::merge(&args),
        Command::Bench(args) => cli::bench(&args),
        Command::Generate(args) => cli::generate(&args),
    };
    if let Err(e) = result {
        cli::print_stderr(format_args!("penumbra: {}", e.message));
        std::process::exit(e.code);
    }
}
