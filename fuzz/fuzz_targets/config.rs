//! The configuration loader on any text (`Config::from_toml_str`, and the robot's
//! `Config::robot_from_toml_str`): it accepts or names the problem, and an accepted
//! configuration prints to TOML that loads back to the same configuration.
#![no_main]

use libfuzzer_sys::fuzz_target;
use ratf_core::config::Config;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let _ = Config::robot_from_toml_str(text);
    match Config::from_toml_str(text) {
        Ok(config) => {
            let printed = config
                .to_toml_string()
                .expect("a loaded configuration prints");
            let again = Config::from_toml_str(&printed).expect("its own print loads");
            assert_eq!(again, config, "{printed}");
        }
        Err(error) => assert!(!error.to_string().is_empty()),
    }
});
