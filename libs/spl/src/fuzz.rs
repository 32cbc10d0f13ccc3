//! Property tests: the three parsers never panic on arbitrary or mutated input, every refusal
//! is counted under its reason, and what the encoders produce always decodes.

use proptest::prelude::*;

use crate::types::{FieldPoint, NaoBody, NaoCommand, NaoHead, NaoStrategy};
use crate::validation::{DropMonitor, DropReason, PacketKind};
use crate::{
    decode_command, decode_debug, decode_gamecontroller, encode_command, encode_debug,
    encode_gamecontroller,
};

fn valid_command() -> Vec<u8> {
    encode_command(&NaoCommand::body(
        NaoBody::GoToPosition,
        NaoStrategy::Passages,
        FieldPoint::new(1000.0, -500.0),
    ))
    .unwrap()
    .to_vec()
}

/// Feed `bytes` to all three decoders, counting refusals as a bridge would.
fn feed_all(bytes: &[u8], monitor: &mut DropMonitor) {
    match decode_command(bytes) {
        Ok(_) => monitor.accepted(PacketKind::Command),
        Err(e) => {
            monitor.record(&e, 0.0);
        }
    }
    match decode_debug(bytes) {
        Ok(_) => monitor.accepted(PacketKind::Debug),
        Err(e) => {
            monitor.record(&e, 0.0);
        }
    }
    match decode_gamecontroller(bytes) {
        Ok(_) => monitor.accepted(PacketKind::GameController),
        Err(e) => {
            monitor.record(&e, 0.0);
        }
    }
}

/// Flip bytes of `base` at the given (index, value) pairs.
fn mutate(base: &[u8], edits: &[(usize, u8)]) -> Vec<u8> {
    let mut b = base.to_vec();
    for (i, v) in edits {
        let n = b.len();
        b[i % n] = *v;
    }
    b
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 2000, ..ProptestConfig::default() })]

    #[test]
    fn arbitrary_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..600)) {
        let mut m = DropMonitor::default();
        feed_all(&bytes, &mut m);
        let c = m.counters();
        // Every packet is either accepted or counted, once per decoder.
        let handled: u64 = [PacketKind::Command, PacketKind::Debug, PacketKind::GameController]
            .iter()
            .map(|k| c.accepted(*k))
            .sum::<u64>()
            + c.total_dropped();
        prop_assert_eq!(handled, 3);
    }

    #[test]
    fn mutated_command_never_panics(edits in proptest::collection::vec((any::<usize>(), any::<u8>()), 0..6),
                                    cut in 0usize..16) {
        let b = mutate(&valid_command(), &edits);
        let _ = decode_command(&b);
        let _ = decode_command(&b[..cut.min(b.len())]);
    }

    #[test]
    fn mutated_debug_never_panics(edits in proptest::collection::vec((any::<usize>(), any::<u8>()), 0..12),
                                  cut in 0usize..400) {
        let b = mutate(&crate::debug::tests::hand_built(), &edits);
        if let Ok(m) = decode_debug(&b) {
            // Anything accepted re-encodes and decodes to the same model.
            let again = decode_debug(&encode_debug(&m).unwrap()).unwrap();
            prop_assert_eq!(again, m);
        }
        let _ = decode_debug(&b[..cut.min(b.len())]);
    }

    #[test]
    fn mutated_gamecontroller_never_panics(edits in proptest::collection::vec((any::<usize>(), any::<u8>()), 0..12),
                                           cut in 0usize..200) {
        let b = mutate(&crate::gamecontroller::tests::hand_built(), &edits);
        if let Ok(s) = decode_gamecontroller(&b) {
            prop_assert_eq!(encode_gamecontroller(&s).unwrap().to_vec(), b.clone());
        }
        let _ = decode_gamecontroller(&b[..cut.min(b.len())]);
    }

    #[test]
    fn encoded_commands_always_decode(body in proptest::option::of(0usize..10),
                                      head in proptest::option::of(0usize..5),
                                      passages in any::<bool>(),
                                      x in -5000.0f32..5000.0, y in -4000.0f32..4000.0) {
        let cmd = NaoCommand {
            body: body.map_or(NaoBody::Keep, |i| NaoBody::ALL[i]),
            head: head.map_or(NaoHead::Keep, |i| NaoHead::ALL[i]),
            strategy: if passages { NaoStrategy::Passages } else { NaoStrategy::Default },
            target: FieldPoint::new(x, y),
            ..Default::default()
        };
        match encode_command(&cmd) {
            Ok(b) => {
                prop_assert_eq!(b.len(), 11);
                let d = decode_command(&b).unwrap();
                prop_assert_eq!(d.body, cmd.body);
                prop_assert_eq!(d.head, cmd.head);
                prop_assert_eq!(d.strategy, cmd.strategy);
            }
            Err(_) => prop_assert!(cmd.body == NaoBody::Keep && cmd.head == NaoHead::Keep),
        }
    }
}

#[test]
fn every_drop_reason_is_counted() {
    let mut m = DropMonitor::new(1.0);
    let dbg = crate::debug::tests::hand_built();
    let gc = crate::gamecontroller::tests::hand_built();
    let cmd = valid_command();

    let mut record = |r: Result<(), crate::PacketError>, t: f64| {
        if let Err(e) = r {
            m.record(&e, t);
        }
    };
    record(decode_debug(&dbg[..100]).map(|_| ()), 0.0); // wrong size
    let mut b = dbg.clone();
    b[9] = 0;
    record(decode_debug(&b).map(|_| ()), 0.1); // wrong header
    let mut b = gc.clone();
    b[4] = 19;
    record(decode_gamecontroller(&b).map(|_| ()), 0.2); // unknown version
    let mut b = dbg.clone();
    b[16..20].copy_from_slice(&f32::NAN.to_le_bytes());
    record(decode_debug(&b).map(|_| ()), 0.3); // non-finite
    let mut b = cmd.clone();
    b[0] = 200;
    record(decode_command(&b).map(|_| ()), 0.4); // invalid value
    let mut b = cmd.clone();
    b[0] = 0;
    b[1] = 0;
    record(decode_command(&b).map(|_| ()), 0.5); // empty
    let filter = crate::SourceFilter::new(["192.168.1.2".parse().unwrap()]);
    record(
        filter.check(PacketKind::Debug, "192.168.1.99:65305".parse().unwrap()),
        0.6,
    ); // unknown source
    record(decode_command(&cmd[..3]).map(|_| ()), 0.7); // wrong size again
    let c = m.counters();
    for reason in DropReason::ALL {
        assert!(c.reason_total(reason) >= 1, "{reason:?} not counted");
    }
    assert_eq!(c.reason_total(DropReason::WrongSize), 2);
    assert_eq!(c.get(PacketKind::Debug, DropReason::WrongSize), 1);
    assert_eq!(c.get(PacketKind::Command, DropReason::WrongSize), 1);
    assert_eq!(c.total_dropped(), 8);
    assert_eq!(
        c.render(),
        "accepted none; dropped command/wrong_size=1 command/invalid_value=1 \
         command/empty_command=1 debug/wrong_size=1 debug/wrong_header=1 debug/non_finite=1 \
         debug/unknown_source=1 gamecontroller/unknown_version=1"
    );
}
