//! The command lines of `ratf tune motors` and `ratf tune gains`: arguments, reports,
//! files. The binary only dispatches here.

use std::fs;
use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use clap::Args;
use ratf_core::config::{Config, WorldProfile};
use ratf_core::identification::motor_csv;
use ratf_core::identification::motor_fit::{MotorFit, excited};
use ratf_core::identification::motor_model::Sample;
use ratf_core::identification::pi_tuning::TuningGoal;

use super::gains::{self, STEP_RAD_S};
use super::motors::{self, StepPlan, WheelReport};
use super::robot::{RECORDING_KIND, from_recording, run_on_robot};
use super::svg::{Panel, time_series};
use crate::apps::run::timestamped_recording;
use crate::devices::Shared;

/// `ratf tune motors`.
#[derive(Debug, Args)]
pub struct MotorsArgs {
    /// Configuration file (the robot's beliefs; in the simulator the world is drawn around
    /// it).
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// Identify the simulated robot's motors (the simulated Mega and motors).
    #[arg(long, conflicts_with_all = ["from_csv", "robot", "from_recording"])]
    pub sim: bool,
    /// On the robot, through its runtime (`--config` is the robot's file; its devices as
    /// `ratf run` opens them): the wheels off the ground, or the robot on the floor with a
    /// metre of room around it. Recorded under `--out`.
    #[arg(long, requires = "config", conflicts_with_all = ["from_csv", "from_recording"])]
    pub robot: bool,
    /// Do not ask before driving (with `--robot`).
    #[arg(long, requires = "robot")]
    pub yes: bool,
    /// Folder for the recording of the steps (with `--robot`).
    #[arg(long, value_name = "DIR", default_value = "out", requires = "robot")]
    pub out: PathBuf,
    /// Fit from a recording of `--robot`'s steps (the core re-run over its inputs; the
    /// battery voltage the run was given is in it).
    #[arg(long, value_name = "FILE", conflicts_with_all = ["from_csv", "battery_v"])]
    pub from_recording: Option<PathBuf>,
    /// Simulator seed.
    #[arg(long, default_value_t = 1, requires = "sim")]
    pub seed: u64,
    /// Simulated world profile (default: the configuration's `[sim] world`).
    #[arg(long, value_enum, requires = "sim")]
    pub world: Option<WorldProfile>,
    /// Fit a log of the original tuning node (`sample_period,pwm,encoder_delta,
    /// ticks_per_rev,angular_speed` per motor).
    #[arg(long, value_name = "FILE")]
    pub from_csv: Option<PathBuf>,
    /// Battery voltage during the steps, V, measured with a multimeter (default: from a CSV
    /// name like `…-11.79V.csv`; in the simulator, the world's true battery; else
    /// `[motor] battery_voltage_v`).
    #[arg(long, value_name = "V")]
    pub battery_v: Option<f64>,
    /// PWM levels of the steps (comma-separated, each 1..=90, at least two).
    #[arg(long, value_delimiter = ',', default_values_t = [30, 45, 60])]
    pub levels: Vec<i16>,
    /// How long each step holds, s (0.2..=3).
    #[arg(long, default_value_t = 1.0)]
    pub step_s: f64,
    /// Rest between steps, s (0.2..=3).
    #[arg(long, default_value_t = 0.6)]
    pub rest_s: f64,
    /// Write an SVG of the measured and modelled speeds.
    #[arg(long, value_name = "FILE")]
    pub svg: Option<PathBuf>,
    /// Write the wheels' mean model into this configuration file (`[motor]
    /// gain_rad_s_per_v`, `time_constant_s`, `dead_zone_v`), starting from `--config`.
    #[arg(long, value_name = "FILE")]
    pub write: Option<PathBuf>,
    /// End with one JSON line: `{"wheels": [{"wheel": 0, "gain_rad_s_per_v": …}, …]}`.
    #[arg(long)]
    pub json: bool,
}

/// `ratf tune gains`.
#[derive(Debug, Args)]
pub struct GainsArgs {
    /// Configuration file whose `[motor]` is the identified model (`ratf tune motors
    /// --write`).
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// The motors' delay as `ratf tune motors` reports it, s.
    #[arg(long, default_value_t = 0.0)]
    pub delay_s: f64,
    /// Closed-loop time constant λ, s (smaller: faster, less margin).
    #[arg(long, default_value_t = TuningGoal::default().closed_loop_s)]
    pub closed_loop_s: f64,
    /// Feed-forward, as a fraction of the inverse motor gain (0: none, as IMC wants).
    #[arg(long, default_value_t = 0.0)]
    pub feed_forward: f64,
    /// No dead-zone compensation (V0 = Vd = 0).
    #[arg(long)]
    pub no_dead_zone: bool,
    /// Write the gains into this configuration file (`[mega]` keys), starting from
    /// `--config`.
    #[arg(long, value_name = "FILE")]
    pub write: Option<PathBuf>,
    /// End with one JSON line with the gains and the predicted step.
    #[arg(long)]
    pub json: bool,
}

fn load(path: Option<&Path>) -> anyhow::Result<(Config, toml::Table)> {
    match path {
        Some(path) => {
            let text = fs::read_to_string(path)
                .with_context(|| format!("reading the configuration {}", path.display()))?;
            let config = Config::from_toml_str(&text)
                .with_context(|| format!("the configuration {}", path.display()))?;
            let table =
                toml::from_str(&text).with_context(|| format!("parsing {}", path.display()))?;
            Ok((config, table))
        }
        None => Ok((Config::default(), toml::Table::new())),
    }
}

fn save(file: &toml::Table, path: &Path, what: &str) -> anyhow::Result<()> {
    let text = toml::to_string(file)?;
    Config::from_toml_str(&text).with_context(|| format!("the configuration with {what}"))?;
    fs::write(path, text).with_context(|| format!("writing {}", path.display()))?;
    std::println!("wrote {what} to {}", path.display());
    Ok(())
}

fn plan_of(args: &MotorsArgs) -> anyhow::Result<StepPlan> {
    let plan = StepPlan {
        levels: args.levels.clone(),
        step_s: args.step_s,
        rest_s: args.rest_s,
    };
    plan.check()?;
    Ok(plan)
}

/// `ratf tune motors`; `interrupt` is Ctrl-C's flag (used with `--robot`).
pub fn motors_command(args: &MotorsArgs, interrupt: &Shared) -> anyhow::Result<()> {
    let (mut config, mut file) = load(args.config.as_deref())?;
    let (wheels, truth) = if args.robot {
        let plan = plan_of(args)?;
        let battery_v = args.battery_v.unwrap_or(config.motor.battery_voltage_v);
        if !args.yes {
            eprint!(
                "The wheels must be off the ground, or the robot on the floor with a metre of \
                 room around it: it will drive {:.0} s of PWM steps up to {} (v, vn, w, both \
                 ways). Battery {battery_v:.2} V (measure it; --battery-v). Drive now? [y/N] ",
                plan.duration_s(),
                plan.levels.iter().max().copied().unwrap_or(0)
            );
            let mut answer = String::new();
            std::io::stdin().read_line(&mut answer)?;
            if !matches!(answer.trim(), "y" | "Y" | "yes") {
                bail!("not driven (answer y to drive)");
            }
        }
        fs::create_dir_all(&args.out)
            .with_context(|| format!("creating {}", args.out.display()))?;
        let recording = timestamped_recording(&args.out, RECORDING_KIND);
        let run = run_on_robot(&config, &plan, battery_v, &recording, interrupt)
            .with_context(|| format!("the steps (recording {})", recording.display()))?;
        std::println!(
            "drove {:.1} s of PWM steps on {} (levels {:?}); battery {battery_v:.2} V; \
             recorded to {}",
            plan.duration_s(),
            config.link.mega_port,
            plan.levels,
            run.recording.display()
        );
        (run.wheels, None)
    } else if let Some(path) = &args.from_recording {
        let wheels =
            from_recording(path).with_context(|| format!("the recording {}", path.display()))?;
        std::println!(
            "{}: {} telemetry batches under the steps",
            path.display(),
            wheels.first().map_or(0, Vec::len)
        );
        (wheels, None)
    } else if let Some(csv) = &args.from_csv {
        let text = fs::read_to_string(csv)
            .with_context(|| format!("reading the CSV log {}", csv.display()))?;
        let name = csv.file_name().and_then(|n| n.to_str()).unwrap_or("");
        let battery_v = args
            .battery_v
            .or_else(|| motor_csv::battery_from_name(name))
            .unwrap_or(config.motor.battery_voltage_v);
        std::println!("{}: battery {battery_v:.2} V", csv.display());
        let wheels = motor_csv::parse(&text, battery_v, f64::from(config.mega.pwm_max))
            .with_context(|| format!("the CSV log {}", csv.display()))?;
        (wheels, None)
    } else if args.sim {
        config.sim.seed = args.seed;
        if let Some(world) = args.world {
            config.sim.world = world;
        }
        let plan = plan_of(args)?;
        let run = motors::run_in_sim(&config, &plan);
        let mut wheels = run.wheels;
        if let Some(measured) = args.battery_v {
            // The team's multimeter reading instead of the truth.
            for s in wheels.iter_mut().flatten() {
                s.voltage_v *= measured / run.battery_v;
            }
        }
        std::println!(
            "simulated {:.1} s of PWM steps (levels {:?}, world {}, seed {}); battery {:.2} V",
            plan.duration_s(),
            plan.levels,
            config.sim.world,
            config.sim.seed,
            args.battery_v.unwrap_or(run.battery_v)
        );
        (wheels, Some(run.truth))
    } else {
        bail!("give --robot (with --config), --sim, --from-recording FILE or --from-csv FILE");
    };
    let fits =
        motors::fit_all(&wheels).map_err(|(wheel, e)| anyhow::anyhow!("wheel {wheel}: {e}"))?;
    let reports: Vec<WheelReport> = fits
        .iter()
        .enumerate()
        .map(|(k, f)| WheelReport::new(k, f))
        .collect();
    std::println!("wheel  K (rad/s)/V   τ s     dead zone V  delay s   RMSE rad/s  R²");
    for r in &reports {
        std::println!(
            "{:>5}  {:>10.3}  {:>6.3}  {:>11.3}  {:>7.3}  {:>10.3}  {:.3}",
            r.wheel,
            r.gain_rad_s_per_v,
            r.time_constant_s,
            r.dead_zone_v,
            r.delay_s,
            r.rmse_rad_s,
            r.r2
        );
    }
    if let Some(truth) = truth {
        for (k, (fit, t)) in fits.iter().zip(&truth).enumerate() {
            let pct = |a: f64, b: f64| (a / b - 1.0) * 100.0;
            std::println!(
                "wheel {k} against the simulated motor (K {:.3}, τ {:.3} s, dead zone {:.3} V): \
                 K {:+.2} %, τ {:+.2} %, dead zone {:+.2} %",
                t.gain_rad_s_per_v,
                t.time_constant_s,
                t.dead_zone_v,
                pct(fit.model.gain_rad_s_per_v, t.gain_rad_s_per_v),
                pct(fit.model.time_constant_s, t.time_constant_s),
                pct(fit.model.dead_zone_v, t.dead_zone_v),
            );
        }
    }
    let mean = motors::mean_model(&fits);
    std::println!(
        "mean: K {:.3} (rad/s)/V, τ {:.3} s, dead zone {:.3} V, delay {:.3} s (then: ratf tune \
         gains --delay-s {:.3})",
        mean.gain_rad_s_per_v,
        mean.time_constant_s,
        mean.dead_zone_v,
        mean.delay_s,
        mean.delay_s
    );
    if let Some(path) = &args.svg {
        fs::write(path, plot(&wheels, &fits))
            .with_context(|| format!("writing {}", path.display()))?;
        std::println!("wrote {}", path.display());
    }
    if let Some(path) = &args.write {
        gains::write_model_into(&mean, &mut file);
        save(&file, path, "the identified [motor] model")?;
    }
    if args.json {
        std::println!("{}", serde_json::json!({ "wheels": reports }));
    }
    Ok(())
}

fn plot(wheels: &[Vec<Sample>], fits: &[MotorFit]) -> String {
    let panels: Vec<Panel> = wheels
        .iter()
        .zip(fits)
        .enumerate()
        .map(|(k, (samples, fit))| {
            let modelled = fit.model.simulate(samples);
            let mask = excited(samples);
            let mut t = 0.0;
            let mut panel = Panel {
                title: format!(
                    "wheel {k}: K {:.3} (rad/s)/V, τ {:.3} s, dead zone {:.3} V, delay {:.3} s, \
                     R² {:.3}",
                    fit.model.gain_rad_s_per_v,
                    fit.model.time_constant_s,
                    fit.model.dead_zone_v,
                    fit.model.delay_s,
                    fit.quality.r2
                ),
                time_s: Vec::new(),
                measured: Vec::new(),
                modelled: Vec::new(),
            };
            for ((s, m), keep) in samples.iter().zip(modelled).zip(mask) {
                t += s.period_s;
                if keep {
                    panel.time_s.push(t);
                    panel.measured.push(s.speed_rad_s);
                    panel.modelled.push(m);
                }
            }
            panel
        })
        .collect();
    time_series(&panels, "rad/s")
}

/// `ratf tune gains`.
pub fn gains_command(args: &GainsArgs) -> anyhow::Result<()> {
    let (config, mut file) = load(args.config.as_deref())?;
    if !(0.0..=0.2).contains(&args.delay_s) {
        bail!(
            "--delay-s {} s: expected 0..0.2 s (ratf tune motors reports it)",
            args.delay_s
        );
    }
    if !(0.005..=2.0).contains(&args.closed_loop_s) {
        bail!(
            "--closed-loop-s {} s: expected 0.005..2 s",
            args.closed_loop_s
        );
    }
    if !(0.0..=1.0).contains(&args.feed_forward) {
        bail!("--feed-forward {}: expected 0..1", args.feed_forward);
    }
    let goal = TuningGoal {
        closed_loop_s: args.closed_loop_s,
        feed_forward: args.feed_forward,
        dead_zone_compensation: !args.no_dead_zone,
    };
    let model = gains::model_of(&config, args.delay_s);
    let tuned = gains::tune(&config, &model, &goal);
    let step = gains::predict(&config, &model, &tuned, STEP_RAD_S);
    std::println!(
        "model: K {:.3} (rad/s)/V, τ {:.3} s, dead zone {:.3} V, delay {:.3} s; battery {:.2} V; \
         λ {:.3} s",
        model.gain_rad_s_per_v,
        model.time_constant_s,
        model.dead_zone_v,
        model.delay_s,
        config.motor.battery_voltage_v,
        goal.closed_loop_s
    );
    std::println!(
        "[mega] kc_v_per_rad_s = {:.6}\n       ki_v_per_rad = {:.6}\n       kf_v_per_rad_s = \
         {:.6}\n       dead_zone_v0_v = {:.6}\n       dead_zone_vd_v = {:.6}",
        tuned.kc_v_per_rad_s,
        tuned.ki_v_per_rad,
        tuned.kf_v_per_rad_s,
        tuned.dead_zone_v0_v,
        tuned.dead_zone_vd_v
    );
    std::println!("predicted {STEP_RAD_S} rad/s step (the Mega's PI against the model):");
    std::println!("  t s    speed rad/s  PWM");
    for (k, (w, pwm)) in step.speed_rad_s.iter().zip(&step.pwm).enumerate().take(20) {
        std::println!(
            "  {:.2}  {:>11.2}  {:>4}",
            (k + 1) as f64 * step.period_s,
            w,
            pwm
        );
    }
    match step.settling_s {
        Some(s) => std::println!(
            "within ±5 % after {:.0} ms; overshoot {:.1} %",
            s * 1e3,
            step.overshoot_pct
        ),
        None => std::println!(
            "never settles within ±5 % in 1 s (overshoot {:.1} %): a slower λ or a stronger \
             battery",
            step.overshoot_pct
        ),
    }
    if let Some(path) = &args.write {
        gains::write_into(&tuned, &mut file);
        save(&file, path, "the tuned [mega] gains")?;
    }
    if args.json {
        std::println!(
            "{}",
            serde_json::json!({
                "gains": tuned,
                "step": {
                    "reference_rad_s": step.reference_rad_s,
                    "settling_s": step.settling_s,
                    "overshoot_pct": step.overshoot_pct,
                },
            })
        );
    }
    Ok(())
}
