//! `host-tools`: the BRDF meter's host command line.
use clap::Parser;

fn main() -> std::process::ExitCode {
    let cli = host_tools::cli::Cli::parse();
    match host_tools::cli::run(cli) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            // `{:#}` prints the whole context chain: what failed, where, why.
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}
