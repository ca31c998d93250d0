use std::process::ExitCode;

use clap::Parser;

fn main() -> ExitCode {
    let cli = propsim::cli::Cli::parse();
    match propsim::cli::run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {}", format!("{e:#}").replace('\n', " "));
            ExitCode::FAILURE
        }
    }
}
