//! `ratf`: the command-line entry point (wiring only).

use clap::{Parser, Subcommand};

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
    }
    Ok(())
}
