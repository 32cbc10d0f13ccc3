//! `speech_model`: build the adapted acoustic model the recognizer prefers (see the library's
//! `adapt` and `model` modules).

use clap::Parser;
use speech_recognition::adapt::{self, Corpus, Progress, Recipe};
use speech_recognition::model::{AcousticModel, adapted_model_dir};
use std::path::PathBuf;
use std::process::ExitCode;

/// Adapt PocketSphinx's stock US English acoustic model (MAP, with SphinxTrain) to noisy speech,
/// so commands survive a noisy room: by default on a corpus synthesized with espeak-ng (every
/// command of both games and ordinary sentences, 14 voices, clean to 5 dB SNR, and the commands
/// again in reverberant rooms, over other people talking and beside a fan), or on your own
/// recordings (`--recordings`). The result goes where `speech_recognition` looks for it first.
///
/// Needs the Debian packages sphinxtrain, sphinxbase-utils, pocketsphinx-en-us and espeak-ng.
/// A build takes about 9 minutes on two cores; it is skipped when the model there was built from
/// the same recipe.
#[derive(Debug, Parser)]
#[command(name = "speech_model")]
struct Args {
    /// Model folder to write (default: the one the recognizer uses).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Adapt on recordings instead: a folder of `NAME.wav` (16-bit PCM, any rate) each with
    /// `NAME.txt` holding its words. Record the robot's users through its own microphone.
    #[arg(long)]
    recordings: Option<PathBuf>,
    /// Rebuild even when the model is up to date.
    #[arg(long)]
    force: bool,
    /// Only say whether the model is up to date (exit 0) or not (exit 1).
    #[arg(long)]
    check: bool,
    /// Only print which model `speech_recognition` loads without `--acoustic-model`: `stock`,
    /// `adapted`, or the folder `$ROBOCOG_ACOUSTIC_MODEL` names.
    #[arg(long)]
    which: bool,
}

fn main() -> ExitCode {
    let args = Args::parse();
    if args.which {
        println!("{}", AcousticModel::default_spec());
        return ExitCode::SUCCESS;
    }
    let out = args.out.clone().unwrap_or_else(adapted_model_dir);
    let recipe = Recipe {
        corpus: match &args.recordings {
            Some(d) => Corpus::Recordings(d.clone()),
            None => Corpus::Synthesized,
        },
        ..Recipe::synthesized()
    };
    let current = recipe.is_built_in(&out);
    if args.check {
        println!(
            "{}: {}",
            out.display(),
            if current {
                "up to date"
            } else {
                "missing or out of date"
            }
        );
        return if current {
            ExitCode::SUCCESS
        } else {
            ExitCode::FAILURE
        };
    }
    if current && !args.force {
        if let Ok(m) = AcousticModel::at(&out) {
            eprintln!("speech_model: up to date: {}", m.describe());
        }
        return ExitCode::SUCCESS;
    }
    eprintln!(
        "speech_model: building the adapted acoustic model into {}",
        out.display()
    );
    #[expect(
        clippy::disallowed_methods,
        reason = "a command-line tool's progress times of an offline model build: a measurement of compute"
    )]
    let t0 = std::time::Instant::now();
    let mut progress = |p: Progress| match p {
        Progress::Step(s) => eprintln!("speech_model: [{:>4.0} s] {s}", t0.elapsed().as_secs_f64()),
        Progress::Corpus { done, total } => eprintln!(
            "speech_model: [{:>4.0} s]   {done}/{total} utterances",
            t0.elapsed().as_secs_f64()
        ),
    };
    match adapt::build(&recipe, &out, &mut progress) {
        Ok(r) => {
            eprintln!(
                "speech_model: done in {:.0} s: {} ({:.0} min of audio)",
                r.seconds,
                r.summary,
                r.audio_s / 60.0
            );
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("speech_model: {e}");
            ExitCode::FAILURE
        }
    }
}
