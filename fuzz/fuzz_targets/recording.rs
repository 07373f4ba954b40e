//! The recording reader (`ratf replay`'s `Recording::from_bytes`) on any bytes: a file that
//! is not a recording, or a damaged or cut one, gives an error or what was readable, never
//! a panic; and what it reads does not change when read twice.
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;
use ratf_host::recording::Recording;

fuzz_target!(|data: &[u8]| {
    let path = Path::new("fuzzed.mcap");
    match Recording::from_bytes(path, data) {
        Ok(recording) => {
            let again = Recording::from_bytes(path, data).expect("read once, read twice");
            assert_eq!(again, recording);
        }
        Err(error) => assert!(error.to_string().contains("fuzzed.mcap"), "{error}"),
    }
});
