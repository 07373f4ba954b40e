//! Where the firmware ELF is, and its size as `avr-size` reports it.
//!
//! simavr calls `exit(1)` when it cannot load an ELF, which kills every test in the binary
//! (avr-toolchain.md §7 pitfall 7), so [`elf_path`] checks the file first and returns an
//! error naming the build command.

use std::fmt;
use std::path::{Path, PathBuf};
use std::process::Command;

/// The release ELF, relative to the workspace root: exactly the file that gets flashed.
pub const ELF_RELATIVE_PATH: &str = "firmware-mega/target/avr-none/release/ratf-firmware-mega.elf";
/// Environment variable that points the tests at another ELF (e.g. a bisected build).
pub const ELF_OVERRIDE_ENV: &str = "RATF_HIL_ELF";
/// The command that builds [`ELF_RELATIVE_PATH`].
pub const BUILD_COMMAND: &str = "cd firmware-mega && cargo build --release";

/// Why the firmware cannot be examined.
#[derive(Debug)]
pub enum FirmwareError {
    /// The ELF does not exist.
    Missing {
        /// Where it was looked for.
        path: PathBuf,
    },
    /// An AVR binutils tool failed or printed something unexpected.
    Tool {
        /// The tool (`avr-size`, `avr-objdump`).
        tool: &'static str,
        /// What went wrong.
        detail: String,
    },
}

impl fmt::Display for FirmwareError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Missing { path } => write!(
                f,
                "firmware ELF not found at {} — build it first: `{BUILD_COMMAND}` \
                 (from the workspace root), or set {ELF_OVERRIDE_ENV}",
                path.display()
            ),
            Self::Tool { tool, detail } => write!(f, "{tool} failed: {detail}"),
        }
    }
}

impl std::error::Error for FirmwareError {}

/// The host workspace root (this crate's parent directory).
pub fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .map(Path::to_path_buf)
        .unwrap_or_else(|| PathBuf::from("."))
}

/// The ELF to test: `$RATF_HIL_ELF` if set, else [`ELF_RELATIVE_PATH`]; an error if the
/// file does not exist.
pub fn elf_path() -> Result<PathBuf, FirmwareError> {
    let path = std::env::var_os(ELF_OVERRIDE_ENV)
        .map(PathBuf::from)
        .unwrap_or_else(|| workspace_root().join(ELF_RELATIVE_PATH));
    if path.is_file() {
        Ok(path)
    } else {
        Err(FirmwareError::Missing { path })
    }
}

/// Memory use of the ELF, bytes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MemoryUse {
    /// Flash: `.text` + `.data` (the initial values of `.data` live in flash).
    pub flash_bytes: u64,
    /// Static RAM: `.data` + `.bss` + `.noinit`.
    pub ram_bytes: u64,
}

/// Run `avr-size -A` on `elf` and sum its sections.
pub fn memory_use(elf: &Path) -> Result<MemoryUse, FirmwareError> {
    let output = Command::new("avr-size")
        .arg("-A")
        .arg(elf)
        .output()
        .map_err(|e| FirmwareError::Tool {
            tool: "avr-size",
            detail: format!("cannot run it ({e}); install binutils-avr"),
        })?;
    if !output.status.success() {
        return Err(FirmwareError::Tool {
            tool: "avr-size",
            detail: String::from_utf8_lossy(&output.stderr).into_owned(),
        });
    }
    parse_size_a(&String::from_utf8_lossy(&output.stdout))
}

/// Parse `avr-size -A` output (`section size addr` lines).
pub fn parse_size_a(text: &str) -> Result<MemoryUse, FirmwareError> {
    let mut sections = std::collections::HashMap::new();
    for line in text.lines() {
        let mut fields = line.split_whitespace();
        if let (Some(name), Some(size)) = (fields.next(), fields.next())
            && name.starts_with('.')
            && let Ok(size) = size.parse::<u64>()
        {
            sections.insert(name.to_owned(), size);
        }
    }
    let get = |name: &str| sections.get(name).copied().unwrap_or(0);
    if !sections.contains_key(".text") {
        return Err(FirmwareError::Tool {
            tool: "avr-size",
            detail: format!("no .text section in its output:\n{text}"),
        });
    }
    Ok(MemoryUse {
        flash_bytes: get(".text") + get(".data"),
        ram_bytes: get(".data") + get(".bss") + get(".noinit"),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_avr_size_sections() {
        let text = "fw.elf  :\nsection      size      addr\n.data          48   8389120\n\
                    .text        1154         0\n.bss           10   8389168\n\
                    .debug_info 90000 0\nTotal 91212\n";
        let used = parse_size_a(text).unwrap();
        assert_eq!(
            used,
            MemoryUse {
                flash_bytes: 1202,
                ram_bytes: 58
            }
        );
    }

    #[test]
    fn missing_text_is_an_error() {
        assert!(parse_size_a("nothing here").is_err());
    }

    #[test]
    fn missing_elf_message_names_the_build_command() {
        let err = FirmwareError::Missing {
            path: PathBuf::from("/nope.elf"),
        };
        assert!(err.to_string().contains(BUILD_COMMAND));
    }
}
