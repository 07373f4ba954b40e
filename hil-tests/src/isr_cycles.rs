//! Static cycle bounds of an interrupt handler, from `avr-objdump -d` of the ELF.
//!
//! avr-tester gives no access to the program counter, and a dynamic profile would need
//! raw (unsafe) simavr calls, so the ISR cost is computed statically: every path from the
//! interrupt vector to `reti` is walked, and its cycles summed with the ATmega2560's
//! instruction timings (AVR Instruction Set Manual, AVRe+ core with a 22-bit PC; simavr's
//! `sim_core.c` charges the same). avr-toolchain.md §3 reports that this static count and a
//! cycle-by-cycle simavr profile agree exactly.
//!
//! The count includes the 5-cycle hardware entry (PC push + vector fetch, which simavr does
//! not charge), the `jmp` in the vector table, the handler, any function it calls, and the
//! 5-cycle `reti`. The analysis fails (with a message) instead of guessing when the handler
//! has a loop (no static bound without loop bounds), an indirect jump or call, or an
//! instruction it has no timing for.

use crate::firmware::FirmwareError;
use std::collections::{BTreeMap, BTreeSet, HashMap, HashSet};
use std::fmt;
use std::path::Path;
use std::process::Command;

/// Cycles the CPU spends entering an interrupt on a 3-byte-PC AVR (ATmega2560 datasheet
/// §7.8.1: "The interrupt execution response … is five clock cycles minimum").
pub const HARDWARE_ENTRY_CYCLES: u64 = 5;
/// Byte address of vector `n` in the ATmega2560's table (4 bytes per vector: a `jmp`).
pub const fn vector_address(n: u32) -> u32 {
    4 * n
}
/// TIMER1_COMPA's vector number on the ATmega2560 (`__vector_17`).
pub const TIMER1_COMPA_VECTOR: u32 = 17;

/// One disassembled instruction.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Instruction {
    /// Byte address.
    pub address: u32,
    /// Size, bytes (2 or 4).
    pub size: u32,
    /// Mnemonic, e.g. `push`.
    pub mnemonic: String,
    /// Operands as printed, comment included (e.g. `.+4 ; 0x1e0 <f+0x58>`).
    pub operands: String,
}

impl Instruction {
    /// The target byte address of a direct jump, branch or call: the address objdump
    /// prints in the comment, or the absolute operand of `jmp`/`call`.
    fn target(&self) -> Option<u32> {
        let text = match self.operands.split_once(';') {
            Some((_, comment)) => comment,
            None => self.operands.as_str(),
        };
        let hex = text
            .split(|c: char| c.is_whitespace() || c == ',')
            .find_map(|tok| tok.strip_prefix("0x"))?;
        u32::from_str_radix(hex, 16).ok()
    }
}

/// Why the bounds could not be computed.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum AnalysisError {
    /// The handler (or a callee) loops: its cost is not bounded without loop bounds.
    Loop {
        /// The address reached twice on one path.
        address: u32,
    },
    /// An indirect jump or call (`ijmp`, `icall`, …): the target is not static.
    Indirect {
        /// Where.
        address: u32,
    },
    /// An instruction with no timing in the table.
    UnknownInstruction {
        /// Where.
        address: u32,
        /// Its mnemonic.
        mnemonic: String,
    },
    /// Every path from here calls a function that never returns (the panic handler, which
    /// loops with interrupts off): not a path the bound has to cover.
    Diverges {
        /// The call.
        address: u32,
    },
    /// A function returns with interrupts still off (its caller's code would have to be
    /// walked too).
    ReturnWithInterruptsOff {
        /// Where.
        address: u32,
    },
    /// Control flow left the disassembled code.
    NoInstruction {
        /// The missing address.
        address: u32,
    },
}

impl fmt::Display for AnalysisError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Loop { address } => write!(
                f,
                "the ISR has a loop through 0x{address:x}: no static cycle bound"
            ),
            Self::Indirect { address } => {
                write!(
                    f,
                    "indirect jump/call at 0x{address:x}: no static cycle bound"
                )
            }
            Self::UnknownInstruction { address, mnemonic } => {
                write!(f, "no cycle count for `{mnemonic}` at 0x{address:x}")
            }
            Self::Diverges { address } => write!(
                f,
                "every path through 0x{address:x} calls a function that never returns"
            ),
            Self::ReturnWithInterruptsOff { address } => write!(
                f,
                "`ret` at 0x{address:x} with interrupts off: the critical section goes on in \
                 the caller"
            ),
            Self::NoInstruction { address } => {
                write!(
                    f,
                    "control flow reaches 0x{address:x}, which was not disassembled"
                )
            }
        }
    }
}

impl std::error::Error for AnalysisError {}

/// Parse `avr-objdump -d` output into instructions by address.
pub fn parse_objdump(text: &str) -> BTreeMap<u32, Instruction> {
    let mut out = BTreeMap::new();
    for line in text.lines() {
        let fields: Vec<&str> = line.split('\t').collect();
        if fields.len() < 3 {
            continue;
        }
        let Some(address) = fields[0]
            .trim()
            .strip_suffix(':')
            .and_then(|a| u32::from_str_radix(a, 16).ok())
        else {
            continue;
        };
        let bytes = fields[1].split_whitespace().count() as u32;
        if bytes == 0 || !fields[1].split_whitespace().all(|b| b.len() == 2) {
            continue;
        }
        out.insert(
            address,
            Instruction {
                address,
                size: bytes,
                mnemonic: fields[2].trim().to_owned(),
                operands: fields[3..].join("\t").trim().to_owned(),
            },
        );
    }
    out
}

/// Disassemble `elf` with `avr-objdump -d`.
pub fn disassemble(elf: &Path) -> Result<BTreeMap<u32, Instruction>, FirmwareError> {
    let output = Command::new("avr-objdump")
        .arg("-d")
        .arg(elf)
        .output()
        .map_err(|e| FirmwareError::Tool {
            tool: "avr-objdump",
            detail: format!("cannot run it ({e}); install binutils-avr"),
        })?;
    if !output.status.success() {
        return Err(FirmwareError::Tool {
            tool: "avr-objdump",
            detail: String::from_utf8_lossy(&output.stderr).into_owned(),
        });
    }
    Ok(parse_objdump(&String::from_utf8_lossy(&output.stdout)))
}

/// Cycle bounds over every path.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CycleBounds {
    /// Shortest path, cycles.
    pub min: u64,
    /// Longest path, cycles.
    pub max: u64,
}

impl CycleBounds {
    fn add(self, cycles: u64) -> Self {
        Self {
            min: self.min + cycles,
            max: self.max + cycles,
        }
    }

    fn join(self, other: Self) -> Self {
        Self {
            min: self.min.min(other.min),
            max: self.max.max(other.max),
        }
    }
}

/// Fixed cost of an instruction that does not change control flow, cycles (ATmega2560).
fn straight_cycles(mnemonic: &str) -> Option<u64> {
    const ONE: &[&str] = &[
        "add", "adc", "sub", "subi", "sbc", "sbci", "and", "andi", "or", "ori", "eor", "com",
        "neg", "sbr", "cbr", "inc", "dec", "tst", "clr", "ser", "mov", "movw", "ldi", "in", "out",
        "lsl", "lsr", "rol", "ror", "asr", "swap", "bset", "bclr", "bst", "bld", "sec", "clc",
        "sen", "cln", "sez", "clz", "sei", "cli", "ses", "cls", "sev", "clv", "set", "clt", "seh",
        "clh", "nop", "wdr", "cp", "cpc", "cpi",
    ];
    const TWO: &[&str] = &[
        "adiw", "sbiw", "mul", "muls", "mulsu", "fmul", "fmuls", "fmulsu", "ld", "ldd", "st",
        "std", "lds", "sts", "push", "pop", "sbi", "cbi",
    ];
    const THREE: &[&str] = &["lpm", "elpm"];
    if ONE.contains(&mnemonic) {
        Some(1)
    } else if TWO.contains(&mnemonic) {
        Some(2)
    } else if THREE.contains(&mnemonic) {
        Some(3)
    } else {
        None
    }
}

const SKIPS: &[&str] = &["cpse", "sbrc", "sbrs", "sbic", "sbis"];

/// Where a walk ends.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
enum End {
    /// At `reti` (an interrupt handler).
    Reti,
    /// At `ret` (a called function).
    Ret,
    /// Where interrupts are enabled again: `sei`, a write of SREG (`out 0x3f`, which in a
    /// critical section restores the saved I flag), or `reti`.
    InterruptsOn,
}

/// The longest instruction, cycles: after `sei` (or an SREG write) the CPU executes one
/// more instruction before a pending interrupt, and an interrupt waits for the current
/// instruction to finish (`call`, `ret`, `reti`: 5 cycles with a 3-byte PC).
pub const LONGEST_INSTRUCTION_CYCLES: u64 = 5;

/// Walks the control-flow graph; memoises per (address, terminator).
struct Walker<'a> {
    code: &'a BTreeMap<u32, Instruction>,
    memo: HashMap<(u32, End), CycleBounds>,
    on_path: HashSet<(u32, End)>,
}

impl Walker<'_> {
    fn new(code: &BTreeMap<u32, Instruction>) -> Walker<'_> {
        Walker {
            code,
            memo: HashMap::new(),
            on_path: HashSet::new(),
        }
    }

    /// Bounds from `address` to the terminator: `reti` when `in_isr`, else `ret`.
    fn bounds(&mut self, address: u32, in_isr: bool) -> Result<CycleBounds, AnalysisError> {
        self.walk(address, if in_isr { End::Reti } else { End::Ret })
    }

    fn walk(&mut self, address: u32, end: End) -> Result<CycleBounds, AnalysisError> {
        let key = (address, end);
        if let Some(b) = self.memo.get(&key) {
            return Ok(*b);
        }
        if !self.on_path.insert(key) {
            return Err(AnalysisError::Loop { address });
        }
        let result = self.bounds_uncached(address, end);
        self.on_path.remove(&key);
        let b = result?;
        self.memo.insert(key, b);
        Ok(b)
    }

    fn instruction(&self, address: u32) -> Result<&Instruction, AnalysisError> {
        self.code
            .get(&address)
            .ok_or(AnalysisError::NoInstruction { address })
    }

    fn target(insn: &Instruction) -> Result<u32, AnalysisError> {
        insn.target().ok_or(AnalysisError::NoInstruction {
            address: insn.address,
        })
    }

    fn bounds_uncached(&mut self, address: u32, end: End) -> Result<CycleBounds, AnalysisError> {
        let insn = self.instruction(address)?.clone();
        let next = address + insn.size;
        let m = insn.mnemonic.as_str();
        let enables = m == "sei" || (m == "out" && insn.operands.starts_with("0x3f"));
        if end == End::InterruptsOn && enables {
            let cycles = 1 + LONGEST_INSTRUCTION_CYCLES;
            return Ok(CycleBounds {
                min: cycles,
                max: cycles,
            });
        }
        let in_isr = end;
        match m {
            "ret" if end == End::InterruptsOn => {
                Err(AnalysisError::ReturnWithInterruptsOff { address })
            }
            "reti" | "ret" => {
                // A `ret` inside the ISR body or a `reti` in a callee would be a miscompile
                // of what we analyse; both cost 5 cycles with a 3-byte PC.
                Ok(CycleBounds { min: 5, max: 5 })
            }
            "rjmp" => Ok(self.walk(Self::target(&insn)?, in_isr)?.add(2)),
            "jmp" => Ok(self.walk(Self::target(&insn)?, in_isr)?.add(3)),
            "rcall" | "call" => {
                let call_cycles = if m == "rcall" { 4 } else { 5 };
                let callee = match self.walk(Self::target(&insn)?, End::Ret) {
                    Err(AnalysisError::Loop { .. } | AnalysisError::Diverges { .. }) => {
                        return Err(AnalysisError::Diverges { address });
                    }
                    other => other?,
                };
                let rest = self.walk(next, in_isr)?;
                Ok(CycleBounds {
                    min: call_cycles + callee.min + rest.min,
                    max: call_cycles + callee.max + rest.max,
                })
            }
            "ijmp" | "eijmp" | "icall" | "eicall" => Err(AnalysisError::Indirect { address }),
            _ if m.starts_with("br") => {
                let fall = self.walk(next, in_isr).map(|b| b.add(1));
                let taken = self.walk(Self::target(&insn)?, in_isr).map(|b| b.add(2));
                join_live(fall, taken)
            }
            _ if SKIPS.contains(&m) => {
                let skipped = self.instruction(next)?;
                let skip_cycles = 1 + u64::from(skipped.size / 2);
                let after = next + skipped.size;
                let no_skip = self.walk(next, in_isr).map(|b| b.add(1));
                let skip = self.walk(after, in_isr).map(|b| b.add(skip_cycles));
                join_live(no_skip, skip)
            }
            _ => {
                let cycles =
                    straight_cycles(m).ok_or_else(|| AnalysisError::UnknownInstruction {
                        address,
                        mnemonic: m.to_owned(),
                    })?;
                Ok(self.walk(next, in_isr)?.add(cycles))
            }
        }
    }
}

/// The bounds over two alternative paths, leaving out one that diverges (see
/// [`AnalysisError::Diverges`]).
fn join_live(
    a: Result<CycleBounds, AnalysisError>,
    b: Result<CycleBounds, AnalysisError>,
) -> Result<CycleBounds, AnalysisError> {
    match (a, b) {
        (Ok(a), Ok(b)) => Ok(a.join(b)),
        (Ok(live), Err(AnalysisError::Diverges { .. }))
        | (Err(AnalysisError::Diverges { .. }), Ok(live)) => Ok(live),
        (Err(e), _) | (_, Err(e)) => Err(e),
    }
}

/// Cycle bounds of interrupt vector `vector`, from the hardware entry to the end of `reti`.
pub fn isr_bounds(
    code: &BTreeMap<u32, Instruction>,
    vector: u32,
) -> Result<CycleBounds, AnalysisError> {
    let mut walker = Walker::new(code);
    Ok(walker
        .bounds(vector_address(vector), true)?
        .add(HARDWARE_ENTRY_CYCLES))
}

/// Cycles interrupts stay off after entering interrupt vector `vector`, until the handler
/// enables them (`sei`, an SREG write, or its `reti`) plus the one instruction the CPU runs
/// before a pending interrupt: the hardware entry, the vector's `jmp` and the handler's
/// prologue up to there.
pub fn vector_interrupts_off(
    code: &BTreeMap<u32, Instruction>,
    vector: u32,
) -> Result<CycleBounds, AnalysisError> {
    Ok(Walker::new(code)
        .walk(vector_address(vector), End::InterruptsOn)?
        .add(HARDWARE_ENTRY_CYCLES))
}

/// Every `cli` in the code with the cycles from it until interrupts are enabled again (the
/// `cli` itself and the instruction after the enabling one included), by address: the
/// critical sections. A `cli` after which interrupts are never enabled again (the panic
/// handler's) gives [`AnalysisError::Loop`].
pub fn critical_sections(
    code: &BTreeMap<u32, Instruction>,
) -> BTreeMap<u32, Result<CycleBounds, AnalysisError>> {
    let mut walker = Walker::new(code);
    code.values()
        .filter(|insn| insn.mnemonic == "cli")
        .map(|insn| {
            let after = insn.address + insn.size;
            let bounds = walker.walk(after, End::InterruptsOn).map(|b| b.add(1));
            (insn.address, bounds)
        })
        .collect()
}

/// ATmega2560 interrupt vectors, the reset vector (0) included.
pub const VECTOR_COUNT: u32 = 57;

/// What a function can do before it returns, for [`Reach`].
#[derive(Clone, Copy, Debug, Default)]
struct FunctionInfo {
    /// It (or a function it calls) can execute a `sei`.
    enables: bool,
    /// It can return (reach a `ret`); a function that never returns (`main`, the panic
    /// handler) is followed by unrelated code, which a call to it does not reach.
    returns: bool,
}

/// Every address control can reach from `starts` (calls followed into the callee, and on
/// after the call when the callee can return; `ret`/`reti` end a path), stopping at `sei`
/// when `stop_at_sei`. With `stop_at_sei`, a call to a function that can execute a `sei`
/// does not continue after the call (interrupts may be on there); those continuations are
/// collected in `enabled`.
struct Reach<'a> {
    code: &'a BTreeMap<u32, Instruction>,
    visited: BTreeSet<u32>,
    enabled: Vec<u32>,
    functions: HashMap<u32, Option<FunctionInfo>>,
}

impl<'a> Reach<'a> {
    fn new(code: &'a BTreeMap<u32, Instruction>) -> Self {
        Self {
            code,
            visited: BTreeSet::new(),
            enabled: Vec::new(),
            functions: HashMap::new(),
        }
    }

    fn instruction(&self, address: u32) -> Result<&'a Instruction, AnalysisError> {
        self.code
            .get(&address)
            .ok_or(AnalysisError::NoInstruction { address })
    }

    /// The addresses control may go to after `insn` within its function, calls apart
    /// (`None` for a call, whose successors depend on the callee).
    fn local_successors(&self, insn: &Instruction) -> Result<Option<Vec<u32>>, AnalysisError> {
        let next = insn.address + insn.size;
        let m = insn.mnemonic.as_str();
        Ok(Some(match m {
            "ret" | "reti" => Vec::new(),
            "jmp" | "rjmp" => vec![Walker::target(insn)?],
            "call" | "rcall" => return Ok(None),
            "ijmp" | "eijmp" | "icall" | "eicall" => {
                return Err(AnalysisError::Indirect {
                    address: insn.address,
                });
            }
            _ if m.starts_with("br") => vec![next, Walker::target(insn)?],
            _ if SKIPS.contains(&m) => {
                let skipped = self.instruction(next)?;
                vec![next, next + skipped.size]
            }
            _ => vec![next],
        }))
    }

    /// What the function at `entry` can do (memoised; a recursive call is assumed to
    /// return and not to enable interrupts).
    fn function(&mut self, entry: u32) -> Result<FunctionInfo, AnalysisError> {
        match self.functions.get(&entry) {
            Some(Some(info)) => return Ok(*info),
            Some(None) => {
                return Ok(FunctionInfo {
                    enables: false,
                    returns: true,
                });
            }
            None => {}
        }
        self.functions.insert(entry, None);
        let mut info = FunctionInfo::default();
        let mut seen = BTreeSet::new();
        let mut stack = vec![entry];
        while let Some(address) = stack.pop() {
            if !seen.insert(address) {
                continue;
            }
            let insn = self.instruction(address)?;
            match insn.mnemonic.as_str() {
                "sei" => info.enables = true,
                "ret" => info.returns = true,
                _ => {}
            }
            match self.local_successors(insn)? {
                Some(next) => stack.extend(next),
                None => {
                    let callee = self.function(Walker::target(insn)?)?;
                    info.enables |= callee.enables;
                    if callee.returns {
                        stack.push(address + insn.size);
                    }
                }
            }
        }
        self.functions.insert(entry, Some(info));
        Ok(info)
    }

    /// Walk from `starts`; see the type's documentation.
    fn walk(&mut self, starts: &[u32], stop_at_sei: bool) -> Result<(), AnalysisError> {
        let mut stack = starts.to_vec();
        while let Some(address) = stack.pop() {
            if !self.visited.insert(address) {
                continue;
            }
            let insn = self.instruction(address)?;
            if stop_at_sei && insn.mnemonic == "sei" {
                continue;
            }
            match self.local_successors(insn)? {
                Some(next) => stack.extend(next),
                None => {
                    let entry = Walker::target(insn)?;
                    stack.push(entry);
                    let callee = self.function(entry)?;
                    let next = address + insn.size;
                    if callee.returns && stop_at_sei && callee.enables {
                        self.enabled.push(next);
                    } else if callee.returns {
                        stack.push(next);
                    }
                }
            }
        }
        Ok(())
    }
}

/// The `cli`s that can run only before interrupts are first enabled (the boot's critical
/// sections): reachable from the reset vector on a path that has not passed a `sei`, and
/// not reachable from any `sei` nor from any interrupt vector the firmware handles. (An
/// unhandled vector jumps, through avr-libc's `__bad_interrupt`, to the reset vector: a
/// restart, so it is left out.) Such a section cannot hold back an encoder sample: the
/// encoder interrupt is not enabled yet.
pub fn boot_only_clis(code: &BTreeMap<u32, Instruction>) -> Result<BTreeSet<u32>, AnalysisError> {
    let mut before = Reach::new(code);
    before.walk(&[vector_address(0)], true)?;
    let restarts = |address: u32| -> bool {
        let Some(insn) = code.get(&address) else {
            return false;
        };
        let Some(handler) = insn.target() else {
            return false;
        };
        handler == vector_address(0)
            || code.get(&handler).is_some_and(|h| {
                matches!(h.mnemonic.as_str(), "jmp" | "rjmp") && h.target() == Some(0)
            })
    };
    let mut starts: Vec<u32> = (1..VECTOR_COUNT)
        .map(vector_address)
        .filter(|&a| code.contains_key(&a) && !restarts(a))
        .collect();
    starts.extend(
        code.values()
            .filter(|i| i.mnemonic == "sei")
            .map(|i| i.address + i.size),
    );
    starts.extend(before.enabled.iter().copied());
    let mut after = Reach::new(code);
    after.walk(&starts, false)?;
    Ok(before
        .visited
        .iter()
        .filter(|a| code.get(a).is_some_and(|i| i.mnemonic == "cli"))
        .filter(|a| !after.visited.contains(a))
        .copied()
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    const LISTING: &str = "
00000000 <__vectors>:
   0:\t0c 94 72 00 \tjmp\t0xe4\t; 0xe4 <__ctors_end>
  44:\t0c 94 c4 00 \tjmp\t0x188\t; 0x188 <__vector_17>

00000188 <__vector_17>:
 188:\t1f 92       \tpush\tr1
 18a:\t0f b6       \tin\tr0, 0x3f\t; 63
 18c:\t80 91 10 02 \tlds\tr24, 0x0210\t; 0x800210 <x>
 190:\t81 11       \tcpse\tr24, r1
 192:\t0e 94 d0 00 \tcall\t0x1a0\t; 0x1a0 <f>
 196:\t88 23       \tand\tr24, r24
 198:\t09 f0       \tbreq\t.+2      \t; 0x19c <__vector_17+0x14>
 19a:\t83 95       \tinc\tr24
 19c:\t1f 90       \tpop\tr1
 19e:\t18 95       \treti

000001a0 <f>:
 1a0:\t00 00       \tnop
 1a2:\t08 95       \tret
";

    #[test]
    fn parses_addresses_sizes_and_targets() {
        let code = parse_objdump(LISTING);
        assert_eq!(code[&0x44].size, 4);
        assert_eq!(code[&0x44].target(), Some(0x188));
        assert_eq!(code[&0x198].mnemonic, "breq");
        assert_eq!(code[&0x198].target(), Some(0x19c));
        assert_eq!(code[&0x192].target(), Some(0x1a0));
    }

    #[test]
    fn bounds_cover_skips_branches_and_calls() {
        let code = parse_objdump(LISTING);
        let b = isr_bounds(&code, 17).unwrap();
        // entry 5 + jmp 3 + push 2 + in 1 + lds 2 = 13 before the cpse.
        // cpse skipping the 2-word call: 3; not skipping: 1 + call 5 + nop 1 + ret 5 = 12.
        // and 1; breq taken 2 / not taken 1 + inc 1 = 2; pop 2 + reti 5 = 7.
        assert_eq!(b.min, 13 + 3 + 1 + 2 + 7);
        assert_eq!(b.max, 13 + 12 + 1 + 2 + 7);
    }

    #[test]
    fn loops_are_reported_not_guessed() {
        let listing = "
  44:\t0c 94 c4 00 \tjmp\t0x188\t; 0x188 <__vector_17>
 188:\t8a 95       \tdec\tr24
 18a:\tf1 f7       \tbrne\t.-4      \t; 0x188 <__vector_17>
 18c:\t18 95       \treti
";
        let code = parse_objdump(listing);
        assert_eq!(
            isr_bounds(&code, 17),
            Err(AnalysisError::Loop { address: 0x188 })
        );
    }

    #[test]
    fn unknown_instructions_are_reported() {
        let listing = "
  44:\t0c 94 c4 00 \tjmp\t0x188\t; 0x188 <__vector_17>
 188:\t88 95       \tsleep
 18a:\t18 95       \treti
";
        let code = parse_objdump(listing);
        assert!(matches!(
            isr_bounds(&code, 17),
            Err(AnalysisError::UnknownInstruction { .. })
        ));
    }
    #[test]
    fn a_cli_before_the_first_sei_is_boot_only_and_one_after_it_is_not() {
        let listing = "
   0:\t0c 94 80 00 \tjmp\t0x100\t; 0x100 <main>
   4:\t0c 94 a0 00 \tjmp\t0x140\t; 0x140 <__vector_1>
   8:\t0c 94 b0 00 \tjmp\t0x160\t; 0x160 <__bad_interrupt>
 100:\tf8 94       \tcli
 102:\t0f be       \tout\t0x3f, r0
 104:\t0e 94 90 00 \tcall\t0x120\t; 0x120 <shared>
 108:\t78 94       \tsei
 10a:\t0e 94 90 00 \tcall\t0x120\t; 0x120 <shared>
 10e:\tf8 94       \tcli
 110:\t0f be       \tout\t0x3f, r0
 112:\tfb cf       \trjmp\t.-10     \t; 0x10a <main+0xa>
 120:\tf8 94       \tcli
 122:\t0f be       \tout\t0x3f, r0
 124:\t08 95       \tret
 140:\tf8 94       \tcli
 142:\t0f be       \tout\t0x3f, r0
 144:\t18 95       \treti
 160:\t0c 94 00 00 \tjmp\t0\t; 0x0 <__vectors>
";
        let code = parse_objdump(listing);
        assert_eq!(boot_only_clis(&code), Ok(BTreeSet::from([0x100])));
    }
}
