//! Raw declarations of the PocketSphinx 0.8+5prealpha C API (the version Debian 12 ships as
//! `libpocketsphinx-dev`), limited to what `speech_recognition` uses: configuration through
//! SphinxBase's `cmd_ln`, a decoder, JSGF and phone-loop searches, raw 16-bit PCM in, hypothesis,
//! score and posterior out.
//!
//! The raw functions are `unsafe` to call; [`decoder::Decoder`] is the safe wrapper the rest of
//! the workspace uses (it lives here because only this crate may contain `unsafe`).
//! Signatures follow `/usr/include/pocketsphinx/{pocketsphinx,ps_search}.h` and
//! `/usr/include/x86_64-linux-gnu/sphinxbase/{cmd_ln,logmath}.h`.

// This crate exists to declare foreign functions, which Rust only allows in `unsafe` blocks; the
// workspace denies unsafe code everywhere else, so the safe wrapper lives here too.
#![allow(unsafe_code)]

pub mod decoder;

use std::ffi::{c_char, c_double, c_int};

/// Opaque SphinxBase configuration (`cmd_ln_t`).
#[repr(C)]
pub struct CmdLn {
    _private: [u8; 0],
}
/// Opaque argument definition table (`arg_t`).
#[repr(C)]
pub struct Arg {
    _private: [u8; 0],
}
/// Opaque decoder (`ps_decoder_t`).
#[repr(C)]
pub struct Decoder {
    _private: [u8; 0],
}
/// Opaque word segment iterator (`ps_seg_t`).
#[repr(C)]
pub struct Seg {
    _private: [u8; 0],
}
/// Opaque N-best iterator (`ps_nbest_t`).
#[repr(C)]
pub struct Nbest {
    _private: [u8; 0],
}
/// Opaque log-domain arithmetic table (`logmath_t`).
#[repr(C)]
pub struct LogMath {
    _private: [u8; 0],
}

unsafe extern "C" {
    /// Parse `argc` strings of `argv` (`-name value` pairs) against `defn` into a new config
    /// (`inout` null). Returns null on an unknown option or a bad value.
    pub fn cmd_ln_parse_r(
        inout: *mut CmdLn,
        defn: *const Arg,
        argc: i32,
        argv: *mut *mut c_char,
        strict: i32,
    ) -> *mut CmdLn;
    /// Release a reference to a config.
    pub fn cmd_ln_free_r(cmdln: *mut CmdLn) -> c_int;

    /// The argument table of the decoder.
    pub fn ps_args() -> *const Arg;
    /// A decoder for `config` (retains it); null on failure (missing model files).
    pub fn ps_init(config: *mut CmdLn) -> *mut Decoder;
    pub fn ps_free(ps: *mut Decoder) -> c_int;
    pub fn ps_get_logmath(ps: *mut Decoder) -> *mut LogMath;

    /// Add a pronunciation (`phones` space-separated; `word(2)` for an alternative of `word`) to
    /// the dictionary; the word id, or < 0 (unknown phone, existing word). `update` non-zero
    /// also adds it to the active search.
    pub fn ps_add_word(
        ps: *mut Decoder,
        word: *const c_char,
        phones: *const c_char,
        update: c_int,
    ) -> c_int;

    /// Add a JSGF grammar from a string as search `name`; < 0 on a parse error.
    pub fn ps_set_jsgf_string(ps: *mut Decoder, name: *const c_char, jsgf: *const c_char) -> c_int;
    /// Add a phone-loop search `name` with an optional phone language model file.
    pub fn ps_set_allphone_file(
        ps: *mut Decoder,
        name: *const c_char,
        path: *const c_char,
    ) -> c_int;
    /// Make search `name` the active one (between utterances only).
    pub fn ps_set_search(ps: *mut Decoder, name: *const c_char) -> c_int;

    pub fn ps_start_utt(ps: *mut Decoder) -> c_int;
    /// Feed `n_samples` 16-bit samples at the configured rate; returns frames searched or < 0.
    pub fn ps_process_raw(
        ps: *mut Decoder,
        data: *const i16,
        n_samples: usize,
        no_search: c_int,
        full_utt: c_int,
    ) -> c_int;
    pub fn ps_end_utt(ps: *mut Decoder) -> c_int;
    /// Best hypothesis (owned by the decoder, valid until the next call) and its path score
    /// (log base of the decoder's logmath, ≤ 0).
    pub fn ps_get_hyp(ps: *mut Decoder, out_best_score: *mut i32) -> *const c_char;
    /// Posterior probability of the best hypothesis in the lattice (log base of the logmath).
    pub fn ps_get_prob(ps: *mut Decoder) -> i32;
    /// Frames (10 ms each at the default frame rate) of the current or last utterance.
    pub fn ps_get_n_frames(ps: *mut Decoder) -> c_int;

    /// Iterate the best path's word segments (null when there is none); free with `ps_seg_free`
    /// unless `ps_seg_next` returned null (which frees it).
    pub fn ps_seg_iter(ps: *mut Decoder) -> *mut Seg;
    pub fn ps_seg_next(seg: *mut Seg) -> *mut Seg;
    pub fn ps_seg_free(seg: *mut Seg);
    /// Posterior of the segment; acoustic, language and back-off scores through the pointers.
    pub fn ps_seg_prob(
        seg: *mut Seg,
        out_ascr: *mut i32,
        out_lscr: *mut i32,
        out_lback: *mut i32,
    ) -> i32;

    /// The N best paths of the last utterance's lattice, best first (null when none);
    /// `ps_nbest_next` returns null at the end (and frees), else free with `ps_nbest_free`.
    pub fn ps_nbest(ps: *mut Decoder) -> *mut Nbest;
    pub fn ps_nbest_next(nbest: *mut Nbest) -> *mut Nbest;
    pub fn ps_nbest_hyp(nbest: *mut Nbest, out_score: *mut i32) -> *const c_char;
    pub fn ps_nbest_free(nbest: *mut Nbest);

    /// `base^logb_p` as a float.
    pub fn logmath_exp(lmath: *mut LogMath, logb_p: c_int) -> c_double;
    /// Natural logarithm of a value given in the logmath's base.
    pub fn logmath_log_to_ln(lmath: *mut LogMath, logb_p: c_int) -> c_double;
}
