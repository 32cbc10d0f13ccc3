#![allow(clippy::unwrap_used, clippy::expect_used)]
#![expect(
    clippy::disallowed_methods,
    reason = "an integration test against a real router and an in-process dialog on the system clock: its waits and time-outs are real time"
)]
//! A command heard while the Executive is away (restarting) is held, the person told "One moment,
//! please.", and carried out as soon as the Executive reads `game/command` again; held too long,
//! it is dropped and the person told so. A command the Executive may have died before acting on is
//! sent again, with its stamp. On a real bus (a router on a free port), with the dialog
//! running in-process.

use dialogs::component::{HOLD_EXPIRED, HOLDING, Hold, run};
use dialogs::machine::DialogConfig;
use interfaces::msg::command::{Command, Game, GameCommand};
use interfaces::msg::speech::{SayRequest, Utterance};
use interfaces::{Bus, Shutdown, topics};
use std::time::Duration;

fn utterance(command: Command) -> Utterance {
    Utterance {
        game: Game::Touch,
        text: command.phrase().to_string(),
        confidence: 0.95,
        command,
        in_grammar: true,
        ..Default::default()
    }
}

async fn said(says: &interfaces::Subscriber<SayRequest>, text: &str) {
    tokio::time::timeout(Duration::from_secs(10), async {
        loop {
            if says.recv().await.unwrap().text == text {
                return;
            }
        }
    })
    .await
    .unwrap_or_else(|_| panic!("the robot did not say {text:?} within 10 s"));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_command_heard_while_the_executive_is_away_is_held_then_carried_out() {
    let (_router, endpoint) = interfaces::router::open_router("tcp/127.0.0.1:0")
        .await
        .unwrap();
    let args = interfaces::ConnectArgs::to_router(
        &endpoint,
        &format!("dialogs-hold-{}", std::process::id()),
    );
    let dialog_bus = Bus::open(&args, "dialogs").await.unwrap();
    let person = Bus::open(&args, "person").await.unwrap();
    let says = person.subscriber(&topics::SPEECH_SAY).await.unwrap();
    let heard = person.publisher(&topics::SPEECH_UTTERANCE).await.unwrap();
    let hold = Hold {
        readers: vec!["executive".into()],
        max: Duration::from_secs(3),
        recognizers: vec![],
        microphones: vec![],
    };
    let (stop, shutdown): (_, Shutdown) = Shutdown::new();
    let dialog = tokio::spawn(run(dialog_bus, DialogConfig::default(), hold, shutdown));
    tokio::time::sleep(Duration::from_millis(300)).await;

    // No Executive: "touch the ball" is held, and the person hears "One moment, please."
    heard
        .publish(&mut utterance(Command::TouchBall))
        .await
        .unwrap();
    said(&says, HOLDING).await;

    // The Executive comes back: the held command reaches it.
    let executive = Bus::open(&args, "executive").await.unwrap();
    let commands = executive.subscriber(&topics::GAME_COMMAND).await.unwrap();
    let touch: GameCommand = tokio::time::timeout(Duration::from_secs(10), commands.recv())
        .await
        .expect("the held command within 10 s of the Executive's return")
        .unwrap();
    assert_eq!(touch.command, Command::TouchBall);

    // While it reads, commands go straight through, and nothing is said about holding.
    heard.publish(&mut utterance(Command::Quit)).await.unwrap();
    let got = tokio::time::timeout(Duration::from_secs(10), commands.recv())
        .await
        .expect("a command within 10 s")
        .unwrap();
    assert_eq!(got.command, Command::Quit);

    // The Executive dies just after the commands reached it (it may not have acted on them)
    // and is back half a second later: both come again, in order, each with its stamp, by which
    // an Executive that did act on one knows it.
    drop(commands);
    drop(executive);
    tokio::time::sleep(Duration::from_millis(500)).await;
    let executive = Bus::open(&args, "executive").await.unwrap();
    let commands = executive.subscriber(&topics::GAME_COMMAND).await.unwrap();
    for sent in [&touch, &got] {
        let again: GameCommand = tokio::time::timeout(Duration::from_secs(10), commands.recv())
            .await
            .expect("the command sent again within 10 s of the Executive's return")
            .unwrap();
        assert_eq!(again.command, sent.command);
        assert_eq!(again.header.stamp_ns, sent.header.stamp_ns);
    }

    // Away again for longer than the hold: the command is dropped, the person told so (and
    // not about "quit", held again without a reader and dropped too, which was carried out).
    drop(commands);
    drop(executive);
    tokio::time::sleep(Duration::from_millis(500)).await;
    heard
        .publish(&mut utterance(Command::ScanBall))
        .await
        .unwrap();
    said(&says, HOLDING).await;
    said(&says, HOLD_EXPIRED).await;
    // Once: "quit" expired half a second before "scan the ball", without a word.
    let more = tokio::time::timeout(Duration::from_millis(1500), says.recv()).await;
    assert!(more.is_err(), "said more: {more:?}");

    stop.send(true).unwrap();
    dialog.await.unwrap().unwrap();
}
