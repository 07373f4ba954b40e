//! Fitting ratf to a team's own robot (issue 16): motor identification from open-loop PWM
//! steps ([`motor_model`], [`motor_fit`], [`motor_csv`]), wheel PI gains from the identified
//! model ([`pi_tuning`]), and the odometry's wheel radius and lx + ly from a drive among
//! the beacons ([`odometry_fit`]). Pure: samples and times in, parameters out; the apps
//! (`ratf tune`, `ratf calibrate odometry`) collect the data and write the configuration.

pub mod motor_csv;
pub mod motor_fit;
pub mod motor_model;
pub mod odometry_fit;
pub mod pi_tuning;

/// Set `[section] key = value` in `file`, a configuration file's table, keeping every other
/// key the team wrote (the mechanism of [`crate::calibration::Calibration::write_into`]).
pub fn set_config_key(file: &mut toml::Table, section: &str, key: &str, value: toml::Value) {
    let entry = file
        .entry(section)
        .or_insert_with(|| toml::Value::Table(toml::Table::new()));
    if !entry.is_table() {
        *entry = toml::Value::Table(toml::Table::new());
    }
    if let toml::Value::Table(table) = entry {
        table.insert(key.to_owned(), value);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn set_config_key_keeps_the_other_keys() {
        let mut file: toml::Table =
            toml::from_str("[mega]\npwm_max = 200\n[sim]\nseed = 3\n").unwrap();
        set_config_key(&mut file, "mega", "kc_v_per_rad_s", 0.5.into());
        set_config_key(&mut file, "motor", "dead_zone_v", 0.3.into());
        let text = toml::to_string(&file).unwrap();
        let back: toml::Table = toml::from_str(&text).unwrap();
        assert_eq!(back["mega"]["pwm_max"].as_integer(), Some(200));
        assert_eq!(back["mega"]["kc_v_per_rad_s"].as_float(), Some(0.5));
        assert_eq!(back["motor"]["dead_zone_v"].as_float(), Some(0.3));
        assert_eq!(back["sim"]["seed"].as_integer(), Some(3));
    }
}
