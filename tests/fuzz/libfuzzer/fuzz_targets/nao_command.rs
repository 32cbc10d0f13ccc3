#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| robocog_fuzz::nao_command(data));
