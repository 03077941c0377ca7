#![no_main]
//! The thesis' `Param.gene` (`key=value`).
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let _ = cordis_core::thesis::parse_gene("Param.gene", &String::from_utf8_lossy(data));
});
