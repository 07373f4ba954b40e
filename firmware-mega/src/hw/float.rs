//! Link avr-libc's hand-written float routines and libgcc ahead of `compiler_builtins`.
//!
//! rustc puts a crate's own native libraries on the link line before the `compiler_builtins`
//! rlib, so avr-libc's strong `__addsf3`, `__mulsf3`, … and libgcc's `__muldi3` win over
//! `compiler_builtins`' weak generic versions, which are 4–7× slower (avr-toolchain.md §3:
//! an f32 PI step costs about 4 950 cycles with the default and about 1 160–1 300 with
//! these). Putting `-lm` in `-C link-arg` does not work: it lands after `compiler_builtins`.

// SAFETY: an empty foreign block: it declares no items, it only adds the libraries to the
// link line. Both are the avr-gcc toolchain's own libraries for this MCU.
#[link(name = "m")]
#[link(name = "gcc")]
unsafe extern "C" {}
