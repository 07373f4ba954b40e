//! The firmware's budgets: the 50 kHz encoder ISR (TIMER1_COMPA, `__vector_17`) fits 100
//! cycles on its longest path, hardware entry and `reti` included (issue 3); once booted,
//! interrupts are never off for more than 24 cycles, which bounds how late an encoder
//! sample can be (issue 16); flash and
//! static RAM fit 32 KiB and 2 KiB. The counts are static (see `isr_cycles`), so they are
//! deterministic and may be asserted exactly.

use ratf_hil_tests::firmware::elf_path;
use ratf_hil_tests::isr_cycles::{TIMER1_COMPA_VECTOR, disassemble, isr_bounds};

/// Budget of the encoder ISR, cycles (issue 3): under a third of the 320-cycle period.
const ISR_BUDGET_CYCLES: u64 = 100;

#[test]
fn encoder_isr_fits_100_cycles() {
    let elf = elf_path().unwrap_or_else(|e| panic!("{e}"));
    let code = disassemble(&elf).unwrap_or_else(|e| panic!("{e}"));
    let bounds = isr_bounds(&code, TIMER1_COMPA_VECTOR)
        .unwrap_or_else(|e| panic!("cannot bound the TIMER1_COMPA ISR: {e}"));
    println!(
        "TIMER1_COMPA ISR: min {} cycles, max {} cycles (entry + vector jmp + body + reti)",
        bounds.min, bounds.max
    );
    assert!(
        bounds.max <= ISR_BUDGET_CYCLES,
        "the encoder ISR takes up to {} cycles, over the {ISR_BUDGET_CYCLES}-cycle budget",
        bounds.max
    );
}

/// The longest time interrupts can stay off once they have been enabled, cycles: every
/// other handler's entry up to its `sei`, and every critical section (`cli` … SREG restore)
/// that can run after the boot. The encoder interrupt can be held off this long, so its
/// sample (the `in` of `PINA`, 17 cycles after the compare match when nothing holds it
/// off) comes at most this much later. Edges are lost when two consecutive samples are
/// further apart than two edges: at 45 000 edges/s that needs the jitter to stay under
/// 355 − 320 = 35 cycles, at 47 000 under 340 − 320 = 20. The worst are the two serial
/// handlers' entries (24: the read-modify-write of `UCSR0B` that turns their own interrupt
/// off before their `sei`); the longest critical sections left are 12 cycles (the
/// read-modify-writes of `UCSR0B`). The boot's sections (`main`'s stack frame set-up,
/// `Peripherals::take`, 48 cycles, and `Encoders::start`) run before interrupts are first
/// enabled (`isr_cycles::boot_only_clis`) and are listed apart.
const MAX_INTERRUPTS_OFF_CYCLES: u64 = 24;

#[test]
fn interrupts_are_never_off_for_more_than_24_cycles_after_boot() {
    use ratf_hil_tests::isr_cycles::{
        AnalysisError, boot_only_clis, critical_sections, vector_interrupts_off,
    };
    let elf = elf_path().unwrap_or_else(|e| panic!("{e}"));
    let code = disassemble(&elf).unwrap_or_else(|e| panic!("{e}"));
    let boot = boot_only_clis(&code).unwrap_or_else(|e| panic!("cannot find the boot: {e}"));
    let mut worst = (0, String::new());
    for (vector, name) in [(25, "USART0_RX"), (26, "USART0_UDRE"), (32, "TIMER3_COMPA")] {
        let off = vector_interrupts_off(&code, vector)
            .unwrap_or_else(|e| panic!("cannot bound {name}'s entry: {e}"));
        println!(
            "{name}: interrupts off for at most {} cycles from its entry",
            off.max
        );
        if off.max > worst.0 {
            worst = (off.max, name.to_owned());
        }
    }
    let mut never_enabled = Vec::new();
    for (address, bounds) in critical_sections(&code) {
        let when = if boot.contains(&address) {
            "boot only, before interrupts are enabled"
        } else {
            "after boot"
        };
        match bounds {
            Ok(b) => {
                println!(
                    "critical section at 0x{address:x}: at most {} cycles ({when})",
                    b.max
                );
                if b.max > worst.0 && !boot.contains(&address) {
                    worst = (b.max, format!("the critical section at 0x{address:x}"));
                }
            }
            // The panic handler disables interrupts for good (and stops the firmware); the
            // boot's `Encoders::start` runs before interrupts are first enabled.
            Err(AnalysisError::Loop { .. } | AnalysisError::Diverges { .. }) => {
                never_enabled.push(address);
            }
            Err(e) => panic!("cannot bound the critical section at 0x{address:x}: {e}"),
        }
    }
    println!(
        "worst after boot: {} cycles ({}); a sample is at most that late; cli not followed by \
         an enable on any returning path (panic handler, boot): {never_enabled:x?}; boot-only \
         cli: {boot:x?}",
        worst.0, worst.1
    );
    assert!(never_enabled.len() <= 3, "{never_enabled:x?}");
    // The boot's three sections (above): a growing list would mean the boot analysis hides
    // sections that run with interrupts on.
    assert!(boot.len() <= 3, "{boot:x?}");
    assert!(
        worst.0 <= MAX_INTERRUPTS_OFF_CYCLES,
        "interrupts can be off for {} cycles ({}), over {MAX_INTERRUPTS_OFF_CYCLES}",
        worst.0,
        worst.1
    );
}

/// The firmware's memory budget (issue 16): 32 KiB of flash, 2 KiB of static RAM.
#[test]
fn flash_and_static_ram_fit_their_budget() {
    use ratf_hil_tests::firmware::memory_use;
    let elf = elf_path().unwrap_or_else(|e| panic!("{e}"));
    let memory = memory_use(&elf).unwrap_or_else(|e| panic!("{e}"));
    println!(
        "flash {} B of 32768, static RAM {} B of 2048",
        memory.flash_bytes, memory.ram_bytes
    );
    assert!(memory.flash_bytes <= 32 * 1024, "{memory:?}");
    assert!(memory.ram_bytes <= 2 * 1024, "{memory:?}");
}
