#![no_main]
//! CSV/TSV with named columns, long or wide, delimiter sniffed through `parse_markers` (`io/markers.rs`): observations or a placed error.
use cordis_core::io::InputFormat;
use libfuzzer_sys::fuzz_target;

#[path = "markers_check.rs"]
mod markers_check;

fuzz_target!(|data: &[u8]| markers_check::check(InputFormat::Csv, "fuzz.csv", data));
