#![no_main]
//! Fuzz target `step`: see fuzz/targets.rs.

// Each target uses one of the shared entry points.
#[allow(dead_code)]
#[path = "../targets.rs"]
mod targets;

libfuzzer_sys::fuzz_target!(|data: &[u8]| targets::step(data));
