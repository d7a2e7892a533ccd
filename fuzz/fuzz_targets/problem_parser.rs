//! Any bytes as a Siconos fc2d problem file: an error or a problem, never a panic or a hang.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        let _ = moreau::io::siconos::parse_fc2d_str(text);
    }
});
