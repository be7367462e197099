//! Tests that the contract atop `src/lib.rs` (which the C header's preamble is made from) says
//! what the code does: the access table of a recording, the outputs released to another queue
//! family and the push-constant bytes.

use super::batch::SCHEDULE;
use super::crowd::{kind, RELEASED_OUTPUTS};
use super::pass::{CrowdBuffer, MAX_PUSH_WORDS};
use ash::vk;
use gpu_allocator::MemoryLocation;

/// The contract, as the lines of the section `## Contract` of lib.rs without their `//! `.
fn contract() -> Vec<&'static str> {
    let lines = include_str!("../lib.rs").lines();
    let lines = lines.map_while(|l| l.strip_prefix("//!").map(str::trim_start));
    let lines: Vec<&str> = lines.skip_while(|l| *l != "## Contract").collect();
    assert!(!lines.is_empty(), "lib.rs has a ## Contract section");
    lines
}

/// The contract's name of buffer `b` (the first column of its access table).
fn row_name(b: CrowdBuffer) -> &'static str {
    match b {
        CrowdBuffer::Bones => "bone transforms, slot f",
        CrowdBuffer::Rhs => "B = [d; q]",
        CrowdBuffer::Palette => "palette [t; q]",
        CrowdBuffer::Positions => "positions (this frame's buffer)",
        CrowdBuffer::Normals => "normals",
        CrowdBuffer::Bounds => "bounds, slot f",
        CrowdBuffer::Tangents => "tangents",
        CrowdBuffer::CorrectiveWeights => "corrective weights",
        CrowdBuffer::Ups => "up vectors, slot f",
    }
}

/// "pass 3" or "passes 1, 2, 3, 5": the contract numbers passes by the phases of the schedule.
fn passes(numbers: &[usize]) -> String {
    let list: Vec<String> = numbers.iter().map(usize::to_string).collect();
    let word = if numbers.len() == 1 { "pass" } else { "passes" };
    format!("{word} {}", list.join(", "))
}

/// The access column of `b`'s row, from the bindings of the table's passes.
fn access(b: CrowdBuffer) -> String {
    let (mut reads, mut writes) = (Vec::new(), Vec::new());
    for (i, phase) in SCHEDULE.iter().enumerate() {
        let (r, w) = (phase.iter().map(|p| p.desc().crowd_accesses()))
            .fold((0, 0), |(r, w), (pr, pw)| (r | pr, w | pw));
        if r & b.bit() != 0 {
            reads.push(i + 1);
        }
        if w & b.bit() != 0 {
            writes.push(i + 1);
        }
    }
    match (writes.is_empty(), reads.is_empty()) {
        (true, _) => format!("compute read ({})", passes(&reads)),
        (false, true) => format!("compute write ({})", passes(&writes)),
        (false, false) => format!(
            "compute write ({}), then read ({})",
            passes(&writes),
            passes(&reads)
        ),
    }
}

/// The memory column's start for `b`, from the usage and location the crowd creates it with.
fn memory(b: CrowdBuffer) -> &'static str {
    let (_, usage, location) = kind(b);
    match (
        location,
        usage.contains(vk::BufferUsageFlags::VERTEX_BUFFER),
    ) {
        (MemoryLocation::CpuToGpu, _) => "host-visible",
        (MemoryLocation::GpuToCpu, _) => "host-visible, cached (read back)",
        (_, true) => "device-local, vertex + storage + transfer-src",
        (_, false) => "device-local, internal",
    }
}

#[test]
fn the_access_table_is_that_of_the_passes_and_buffers() {
    let contract = contract();
    for b in CrowdBuffer::ALL {
        let row = format!("| {} | {} | {}", row_name(b), access(b), memory(b));
        assert!(
            contract.iter().any(|l| l.starts_with(&row)),
            "lib.rs's contract lacks the row `{row}` for {b:?}"
        );
    }
}

/// `text`'s words, without the comment markers of doc lines.
fn words(text: &str) -> String {
    let words = text
        .split_whitespace()
        .filter(|w| !matches!(*w, "///" | "//!"));
    words.collect::<Vec<_>>().join(" ")
}

#[test]
fn the_contract_and_the_options_name_the_released_outputs() {
    let names = RELEASED_OUTPUTS.map(|b| match b {
        CrowdBuffer::Positions => "its positions",
        CrowdBuffer::Normals => "the normals",
        CrowdBuffer::Bounds => "its bounds",
        CrowdBuffer::Tangents => "the tangents",
        b => panic!("{b:?} is not an output"),
    });
    let list = names.join(", ");
    for (file, text) in [
        ("lib.rs's contract", contract().join(" ")),
        (
            "crowd.rs (CrowdOptions)",
            include_str!("crowd.rs").to_string(),
        ),
        (
            "ffi/types.rs (RrskinCrowdOptions)",
            include_str!("../ffi/types.rs").to_string(),
        ),
    ] {
        assert!(
            words(&text).contains(&list),
            "{file} does not list `{list}`"
        );
    }
}

#[test]
fn the_contract_gives_the_push_constant_bytes() {
    let bytes = format!("push constants (bytes 0..{})", 4 * MAX_PUSH_WORDS);
    assert!(words(&contract().join(" ")).contains(&bytes), "{bytes}");
}
