//! `ratf tune motors --from-csv` on the real floor data (an excerpt of the original robot's
//! log, `../shared/data/motor-pwm-steps-11.79V.csv`: PWM ±40/±60 in the v pattern and
//! +30/+45 in the w pattern) and `ratf tune gains` on the identified model, through the
//! binary.

mod common;

use std::path::PathBuf;

/// `ratf ARGS`, which must succeed; its stdout.
fn ratf(args: &[&str]) -> String {
    String::from_utf8(common::ratf_ok(args).stdout).expect("utf-8")
}

fn excerpt() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/motor-pwm-steps-excerpt-11.79V.csv")
}

#[test]
fn tune_motors_fits_the_real_steps_with_r2_above_0_9_per_wheel() {
    let dir = std::env::temp_dir().join(format!("ratf-tune-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let svg = dir.join("fit.svg");
    let config = dir.join("robot.toml");
    let csv = excerpt();
    let stdout = ratf(&[
        "tune",
        "motors",
        "--from-csv",
        csv.to_str().unwrap(),
        "--svg",
        svg.to_str().unwrap(),
        "--write",
        config.to_str().unwrap(),
        "--json",
    ]);
    assert!(stdout.contains("battery 11.79 V"), "{stdout}");
    let last = stdout.lines().last().unwrap();
    let json: serde_json::Value = serde_json::from_str(last).unwrap();
    let wheels = json["wheels"].as_array().unwrap();
    assert_eq!(wheels.len(), 4);
    for (k, w) in wheels.iter().enumerate() {
        assert_eq!(w["wheel"].as_u64(), Some(k as u64));
        let get = |key: &str| w[key].as_f64().unwrap();
        assert!(get("r2") >= 0.9, "{w}");
        // The floor data's figures (README, "Fit your robot"): K 2.2, τ 0.03 s, dead zone
        // 0.2–0.3 V, delay 0.03 s.
        assert!((2.0..2.5).contains(&get("gain_rad_s_per_v")), "{w}");
        assert!((0.02..0.05).contains(&get("time_constant_s")), "{w}");
        assert!((0.15..0.35).contains(&get("dead_zone_v")), "{w}");
        assert!((0.015..0.045).contains(&get("delay_s")), "{w}");
        assert!(get("rmse_rad_s") < 0.2, "{w}");
    }
    assert!(std::fs::read_to_string(&svg).unwrap().contains("<polyline"));

    let gains = ratf(&[
        "tune",
        "gains",
        "--config",
        config.to_str().unwrap(),
        "--delay-s",
        "0.03",
        "--write",
        config.to_str().unwrap(),
        "--json",
    ]);
    let json: serde_json::Value = serde_json::from_str(gains.lines().last().unwrap()).unwrap();
    assert!(
        json["step"]["settling_s"].as_f64().unwrap() <= 0.3,
        "{json}"
    );
    assert!(
        json["step"]["overshoot_pct"].as_f64().unwrap() <= 5.0,
        "{json}"
    );
    let written = std::fs::read_to_string(&config).unwrap();
    assert!(written.contains("kc_v_per_rad_s") && written.contains("gain_rad_s_per_v"));
    std::fs::remove_dir_all(&dir).unwrap();
}
