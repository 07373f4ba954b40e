//! `ratf`: the command-line entry point (wiring only).

use std::path::PathBuf;

use anyhow::Context;
use clap::{Args, Parser, Subcommand};
use ratf_host::config::{Config, ConfigError};

/// ratf: the Robot@Factory 4.0 robot, on the robot or in simulation.
#[derive(Debug, Parser)]
#[command(version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Print the protocol's golden frames (a quick check that the build works).
    Frames,
    /// Print the default configuration or check a configuration file.
    Config(ConfigArgs),
}

#[derive(Debug, Args)]
#[group(required = true, multiple = false)]
struct ConfigArgs {
    /// Print the default configuration (the competition robot) as TOML.
    #[arg(long)]
    print_default: bool,
    /// Parse and validate FILE; print every problem with its key, exit non-zero if any.
    #[arg(long, value_name = "FILE")]
    check: Option<PathBuf>,
}

fn main() -> anyhow::Result<()> {
    let cli = Cli::parse();
    match cli.command {
        Command::Frames => {
            use ratf_protocol::messages::{Command as MegaCommand, Wheel};
            let frame = MegaCommand::WheelSpeed {
                wheel: Wheel::BackRight,
                speed_rad_s: 1.0,
            }
            .to_frame();
            println!("{}", String::from_utf8_lossy(&frame.encode()));
        }
        Command::Config(args) => {
            if let Some(path) = args.check {
                match Config::load(&path) {
                    Ok(_) => println!("{}: ok", path.display()),
                    Err(ConfigError::Invalid { issues, .. }) => {
                        eprintln!("{}: {} invalid value(s):", path.display(), issues.len());
                        for issue in issues {
                            eprintln!("  {issue}");
                        }
                        std::process::exit(1);
                    }
                    Err(e) => {
                        eprintln!("{e}");
                        std::process::exit(1);
                    }
                }
            } else {
                let text = Config::default()
                    .to_toml_string()
                    .context("serialising the default configuration")?;
                print!("{text}");
            }
        }
    }
    Ok(())
}
