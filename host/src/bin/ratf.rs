//! `ratf`: the command-line entry point (wiring only).

use std::fs::{self, File};
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context;
use clap::{Args, Parser, Subcommand};
use ratf_host::config::{Config, ConfigError};
use ratf_host::field::Field;
use ratf_host::plot::FieldPlot;
use ratf_host::sim::collision::OrientedRect;
use ratf_host::sim::drive::{self, DriveReport, DriveTrace};
use ratf_host::sim::scripts::Named;

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
    /// Drive the simulated robot through a velocity script and measure odometry drift.
    Drive(DriveArgs),
}

#[derive(Debug, Args)]
struct DriveArgs {
    /// The script: square, figure-eight, dash, or all.
    #[arg(long, default_value = "all")]
    script: String,
    /// Random seed (overrides the configuration's `sim.seed`).
    #[arg(long)]
    seed: Option<u64>,
    /// Configuration file (defaults: the competition robot).
    #[arg(long, value_name = "FILE")]
    config: Option<PathBuf>,
    /// Directory for the SVG plots and JSON-lines logs.
    #[arg(long, value_name = "DIR", default_value = "out")]
    out: PathBuf,
    /// Print one JSON object with every script's figures as the last line of stdout.
    #[arg(long)]
    json: bool,
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
        Command::Drive(args) => drive_command(&args)?,
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

/// Append `value` as one JSON line.
fn write_json_line(out: &mut impl Write, value: &impl serde::Serialize) -> anyhow::Result<()> {
    serde_json::to_writer(&mut *out, value)?;
    out.write_all(b"\n")?;
    Ok(())
}

/// The configuration from `path`, or the defaults.
fn load_config(path: Option<&Path>) -> anyhow::Result<Config> {
    match path {
        Some(path) => Ok(Config::load(path)?),
        None => Ok(Config::default()),
    }
}

fn drive_command(args: &DriveArgs) -> anyhow::Result<()> {
    let mut config = load_config(args.config.as_deref())?;
    if let Some(seed) = args.seed {
        config.sim.seed = seed;
    }
    let scripts: Vec<Named> = if args.script == "all" {
        Named::ALL.to_vec()
    } else {
        vec![args.script.parse()?]
    };
    fs::create_dir_all(&args.out)
        .with_context(|| format!("creating the output directory {}", args.out.display()))?;
    println!(
        "{:<13} {:>7} {:>8} {:>10} {:>10} {:>10} {:>9} {:>6} {:>6} {:>9}",
        "script",
        "sim s",
        "path m",
        "end err m",
        "end err °",
        "max err m",
        "max err °",
        "slip",
        "coll",
        "sim speed"
    );
    let mut reports = Vec::new();
    for named in scripts {
        let log_path = args.out.join(format!("drive-{named}.jsonl"));
        let mut log = BufWriter::new(
            File::create(&log_path).with_context(|| format!("creating {}", log_path.display()))?,
        );
        let mut write_result = Ok(());
        let started = Instant::now();
        let (report, trace) = drive::run(&config, named, |record| {
            if write_result.is_ok() {
                write_result = write_json_line(&mut log, record);
            }
        })?;
        let wall_s = started.elapsed().as_secs_f64();
        write_result
            .and_then(|()| write_json_line(&mut log, &report))
            .and_then(|()| Ok(log.flush()?))
            .with_context(|| format!("writing {}", log_path.display()))?;
        let svg_path = args.out.join(format!("drive-{named}.svg"));
        fs::write(&svg_path, plot_drive(&config, &report, &trace))
            .with_context(|| format!("writing {}", svg_path.display()))?;
        println!(
            "{:<13} {:>7.1} {:>8.2} {:>10.4} {:>10.2} {:>10.4} {:>9.2} {:>6} {:>6} {:>8.0}x",
            report.script,
            report.sim_s,
            report.distance_m,
            report.final_pos_err_m,
            report.final_heading_err_deg,
            report.max_pos_err_m,
            report.max_heading_err_deg,
            report.slip_steps,
            report.collisions,
            report.sim_s / wall_s.max(1e-9)
        );
        for c in &trace.collisions {
            println!(
                "  collision at {:.2} s with {:?}, robot at ({:.3}, {:.3}) m",
                c.time_us as f64 * 1e-6,
                c.with,
                c.pose.x,
                c.pose.y
            );
        }
        reports.push((report, wall_s));
    }
    println!(
        "wrote {} (SVG plots and JSON-lines logs); sim speed = simulated s per wall s",
        args.out.display()
    );
    if args.json {
        let runs: Vec<serde_json::Value> = reports
            .iter()
            .map(|(report, wall_s)| {
                let mut value = serde_json::to_value(report).unwrap_or_default();
                value["wall_s"] = serde_json::json!(wall_s);
                value
            })
            .collect();
        println!("{}", serde_json::json!({ "drives": runs }));
    }
    Ok(())
}

/// The field with the true path, the odometry, footprints once a second and collisions.
fn plot_drive(config: &Config, report: &DriveReport, trace: &DriveTrace) -> String {
    let mut plot = FieldPlot::new(&Field::competition());
    for &pose in &trace.footprints {
        let footprint = OrientedRect::new(
            pose,
            config.robot.footprint_length_m,
            config.robot.footprint_width_m,
        );
        plot.outline(&footprint.corners(), "#4a7bd0");
    }
    plot.path(&trace.truth, "#1f4e9c", false, "ground truth");
    plot.path(&trace.odometry, "#e07b00", true, "wheel odometry");
    for collision in &trace.collisions {
        plot.mark(
            collision.pose.position(),
            "#d01010",
            &format!("{:?}", collision.with),
        );
    }
    plot.finish(&format!(
        "ratf drive {}: {:.2} m, odometry error at the end {:.1} mm / {:.2} deg, {} collisions",
        report.script,
        report.distance_m,
        report.final_pos_err_m * 1000.0,
        report.final_heading_err_deg,
        report.collisions
    ))
}
