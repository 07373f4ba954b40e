//! Hardware-in-the-loop tests for the Mega firmware: the release ELF, exactly as it will be
//! flashed, run in simavr.
#![forbid(unsafe_code)]
