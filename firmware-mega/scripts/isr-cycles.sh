#!/bin/sh
# Static cycle count of the encoder interrupt (TIMER1_COMPA, __vector_17) from the release ELF.
#
# The handler is straight-line code (the script fails if it finds a branch or an instruction it
# has no timing for), so its cost is the sum of its instructions' cycles on the ATmega2560
# (3-byte PC: RETI 5), plus the 5-cycle hardware entry and the vector table's JMP (3).
# Timings: AVR Instruction Set Manual, ATmega2560 column.
#
# Usage: scripts/isr-cycles.sh [path/to/ratf-firmware-mega.elf]
set -eu
elf=${1:-target/avr-none/release/ratf-firmware-mega.elf}
avr-objdump -d "$elf" | awk '
  /<__vector_17>:/ { inside = 1; next }
  inside && /^[[:space:]]*[0-9a-f]+:/ {
    op = $0; sub(/^[^\t]*\t[^\t]*\t/, "", op); split(op, f, /[ \t]+/); m = f[1]
    if (m ~ /^(in|out|mov|swap|andi|or|add|ldi|eor|and|ori|subi|sbci|inc|dec|lsr|lsl|clr)$/) c = 1
    else if (m ~ /^(push|pop|lds|sts|adiw|sbiw)$/) c = 2
    else if (m == "lpm") c = 3
    else if (m == "reti") c = 5
    else { printf "unexpected instruction in the ISR: %s\n", op > "/dev/stderr"; exit 2 }
    printf "%2d  %s\n", c, op
    body += c
    if (m == "reti") { done = 1; exit }
  }
  END {
    if (!done) { print "no __vector_17 ending in reti found" > "/dev/stderr"; exit 2 }
    printf "instructions (reti included): %d cycles\n", body
    printf "hardware entry 5 + vector-table jmp 3 + handler = %d cycles per interrupt\n", body + 8
  }'
