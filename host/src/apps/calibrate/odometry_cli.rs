//! The command line of `ratf calibrate odometry`: one seed with its figures, or many
//! seeds' spread; `--write` sets the `[robot]` keys.

use std::fs;
use std::path::PathBuf;

use anyhow::Context;
use clap::Args;
use ratf_core::config::{Config, WorldProfile};

use super::odometry::{SimOdometry, run_in_sim};

/// `ratf calibrate odometry`.
#[derive(Debug, Args)]
pub struct OdometryArgs {
    /// Configuration file (the robot's beliefs; the world is drawn around it).
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// Simulator seed (the first of `--seeds`).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Calibrate this many seeds' worlds and report the spread of the errors.
    #[arg(long, default_value_t = 1)]
    pub seeds: u64,
    /// Simulated world profile (default: the configuration's `[sim] world`).
    #[arg(long, value_enum)]
    pub world: Option<WorldProfile>,
    /// Write the configuration with the fitted `[robot] wheel_diameter_m`,
    /// `front_back_wheel_distance_m` and `left_right_wheel_distance_m` (one seed only).
    #[arg(long, value_name = "FILE")]
    pub write: Option<PathBuf>,
    /// End with one JSON line with every seed's figures.
    #[arg(long)]
    pub json: bool,
}

/// `ratf calibrate odometry`.
pub fn odometry_command(args: &OdometryArgs) -> anyhow::Result<()> {
    let (mut config, mut file) = match &args.config {
        Some(path) => {
            let text = fs::read_to_string(path)
                .with_context(|| format!("reading the configuration {}", path.display()))?;
            let config = Config::from_toml_str(&text)
                .with_context(|| format!("the configuration {}", path.display()))?;
            (config, toml::from_str(&text)?)
        }
        None => (Config::default(), toml::Table::new()),
    };
    if let Some(world) = args.world {
        config.sim.world = world;
    }
    if args.write.is_some() && args.seeds != 1 {
        anyhow::bail!("--write takes one seed's fit: drop --seeds");
    }
    let mut runs: Vec<SimOdometry> = Vec::new();
    for seed in args.seed..args.seed + args.seeds.max(1) {
        config.sim.seed = seed;
        let run = run_in_sim(&config).with_context(|| format!("seed {seed}"))?;
        let f = &run.fit;
        std::println!(
            "seed {seed}: wheel diameter {:.5} m (truth {:.5}; error {:+.3} %, before {:+.3} %); \
             lx+ly {:.5} m (truth {:.5}; error {:+.3} %, before {:+.3} %); strafe ×{:.3}; \
             {} of {} stops fixed, {:.2} m straight, {:.2} rad turned, residual {:.1} mm, \
             {} collisions",
            f.wheel_diameter_m,
            run.true_wheel_diameter_m,
            run.radius_error_pct,
            run.uncalibrated_radius_error_pct,
            f.lx_plus_ly_m,
            run.true_lx_plus_ly_m,
            run.lx_plus_ly_error_pct,
            run.uncalibrated_lx_plus_ly_error_pct,
            f.strafe_factor,
            run.fixed_stops[0],
            run.fixed_stops[1],
            f.straight_m,
            f.turned_rad,
            f.residual_m * 1e3,
            run.collisions
        );
        runs.push(run);
    }
    let worst =
        |f: &dyn Fn(&SimOdometry) -> f64| runs.iter().map(|r| f(r).abs()).fold(0.0, f64::max);
    let mean = |f: &dyn Fn(&SimOdometry) -> f64| {
        runs.iter().map(|r| f(r).abs()).sum::<f64>() / runs.len().max(1) as f64
    };
    std::println!(
        "{} seeds ({} world): |wheel radius error| mean {:.3} %, worst {:.3} % (before: worst \
         {:.3} %); |lx+ly error| mean {:.3} %, worst {:.3} % (before: worst {:.3} %)",
        runs.len(),
        config.sim.world,
        mean(&|r| r.radius_error_pct),
        worst(&|r| r.radius_error_pct),
        worst(&|r| r.uncalibrated_radius_error_pct),
        mean(&|r| r.lx_plus_ly_error_pct),
        worst(&|r| r.lx_plus_ly_error_pct),
        worst(&|r| r.uncalibrated_lx_plus_ly_error_pct),
    );
    if let (Some(path), Some(run)) = (&args.write, runs.first()) {
        run.fit.write_into(&config, &mut file);
        let text = toml::to_string(&file)?;
        Config::from_toml_str(&text).context("the calibrated configuration")?;
        fs::write(path, text).with_context(|| format!("writing {}", path.display()))?;
        std::println!("wrote the odometry calibration to {}", path.display());
    }
    if args.json {
        std::println!("{}", serde_json::json!({ "runs": runs }));
    }
    Ok(())
}
