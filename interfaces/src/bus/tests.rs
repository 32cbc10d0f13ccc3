use super::*;
use crate::msg::vision::{Intrinsics, RgbdFrame};
use crate::topics;
use std::collections::BTreeMap;

async fn two_buses() -> (zenoh::Session, Bus, Bus) {
    let (router, endpoint) = crate::router::open_router("tcp/127.0.0.1:0").await.unwrap();
    let ns = format!("unit-bus-{}", std::process::id());
    let args = ConnectArgs::to_router(&endpoint, &ns);
    let a = Bus::open(&args, "unit-a").await.unwrap();
    let b = Bus::open(&args, "unit-b").await.unwrap();
    (router, a, b)
}

fn frame(seq_tag: u8) -> RgbdFrame {
    let mut f = RgbdFrame::blank(640, 480, Intrinsics::default());
    f.header.frame_id = "head_rgbd_optical_frame".into();
    f.header.stamp_ns = 1;
    f.rgb.fill(seq_tag);
    f.depth_mm.fill(seq_tag.wrapping_add(1));
    f
}

async fn next(sub: &Subscriber<RgbdFrame>) -> Received<RgbdFrame> {
    tokio::time::timeout(Duration::from_secs(10), sub.recv_borrowed())
        .await
        .expect("a frame within 10 s")
        .unwrap()
}

/// A foreign client's request that does not decode gets a `BadRequest` reply, counted in
/// `bad_requests/<service>`, and the service goes on answering; a good raw request gets the
/// value back.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn raw_calls_get_bad_request_for_garbage_and_the_value_otherwise() {
    use crate::msg::std_msgs::Text;
    use crate::raw::RawReply;
    let (_router, server, client) = two_buses().await;
    let _served = server
        .serve(&topics::ECHO, |req: Text| async move { Ok(req) })
        .await
        .unwrap();
    let t = Duration::from_secs(5);
    let hello = Text {
        text: "hello".into(),
        ..Text::default()
    };
    let bytes = codec::encode(&hello, "robocog.Text").unwrap();
    // The server's queryable reaches the client through the router a moment after `serve`
    // returns: until then a call finds nobody (and reaches no counter).
    let deadline = Instant::now() + Duration::from_secs(10);
    loop {
        match client
            .raw_call("echo", "robocog.Text", bytes.clone(), t)
            .await
        {
            Err(CallError::NoServer(_)) if Instant::now() < deadline => {
                tokio::time::sleep(Duration::from_millis(20)).await
            }
            other => {
                other.unwrap();
                break;
            }
        }
    }
    let garbage: [Vec<u8>; 4] = [
        vec![],
        vec![0x00, 0x01],
        vec![0xff, 0xff, 0x00, 0x00, 1, 2, 3, 4],
        // A good encapsulation, a header's stamp, and then its frame id's length: 2^32-1.
        [&codec::CDR_LE_HEADER[..], &[0; 8], &[0xff; 4]].concat(),
    ];
    for g in garbage {
        let reply = client
            .raw_call("echo", "robocog.Text", g.clone(), t)
            .await
            .unwrap();
        match reply {
            RawReply::Err(e) => assert_eq!(e.code, ErrorCode::BadRequest, "{g:02x?}: {e}"),
            RawReply::Ok(_) => panic!("{g:02x?} was answered with a value"),
        }
    }
    assert_eq!(
        server
            .counters()
            .counter("bad_requests/echo")
            .load(Ordering::Relaxed),
        4
    );
    let reply = client
        .raw_call("echo", "robocog.Text", bytes, t)
        .await
        .unwrap();
    let back: Text = reply.value().unwrap().unwrap();
    assert_eq!(back.text, "hello");
    let typed = client.call(&topics::ECHO, &hello, t).await.unwrap();
    assert_eq!(typed.text, "hello");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn frames_are_read_in_place_and_bad_payloads_are_counted_drops() {
    let (_router, a, b) = two_buses().await;
    let frames = b.subscriber(&topics::BENCH_FRAME).await.unwrap();
    let publisher = a.publisher(&topics::BENCH_FRAME).await.unwrap();
    tokio::time::sleep(Duration::from_millis(300)).await;

    let mut sent = frame(7);
    publisher.publish(&mut sent).await.unwrap();
    let got = next(&frames).await;
    assert!(got.is_shm(), "a 1.5 MB frame travels in shared memory");
    let view = got.view();
    assert_eq!(view.header, sent.header);
    assert!(view.is_consistent());
    assert!(view.rgb.iter().all(|&b| b == 7) && view.depth_mm.iter().all(|&b| b == 8));
    assert_eq!(got.to_message().unwrap(), sent);
    assert_eq!((frames.received(), frames.shm_received()), (1, 1));
    drop(got);

    // Garbage on the topic: truncated, lengths of 2^32-1, no header. Each is a counted drop
    // (and no multi-GiB allocation); the good frame after them comes through.
    let good = codec::encode(&frame(1), RgbdFrame::TYPE_NAME).unwrap();
    // The colour image's length field: the first 640 x 480 x 3 in the payload.
    let rgb_len_at = good
        .windows(4)
        .position(|w| w == (640u32 * 480 * 3).to_le_bytes())
        .unwrap();
    let mut huge_rgb = good.clone();
    huge_rgb[rgb_len_at..rgb_len_at + 4].copy_from_slice(&u32::MAX.to_le_bytes());
    let mut huge_id = good.clone();
    huge_id[12..16].copy_from_slice(&u32::MAX.to_le_bytes());
    let garbage = [
        good[..good.len() - 1].to_vec(),
        good[..100].to_vec(),
        huge_rgb,
        huge_id,
        vec![0, 1],
        Vec::new(),
    ];
    let n_bad = garbage.len() as u64;
    for g in garbage {
        publisher.put_encoded(g).await.unwrap();
    }
    let mut sent = frame(9);
    publisher.publish(&mut sent).await.unwrap();
    let got = next(&frames).await;
    assert_eq!(got.view().header.seq, sent.header.seq);
    assert_eq!(got.view().rgb[0], 9);
    assert_eq!(frames.decode_errors(), n_bad);
    assert_eq!(frames.received(), 2 + n_bad);
    let counters: BTreeMap<String, u64> = b.counters().snapshot().into_iter().collect();
    assert_eq!(counters.get("decode_errors/bench/frame"), Some(&n_bad));
    // Both good frames came in shared memory (big garbage may too: zenoh moves large
    // payloads into shared memory by itself); the bus counter agrees with the subscriber's.
    assert!(frames.shm_received() >= 2);
    assert_eq!(
        counters.get("shm_received/bench/frame"),
        Some(&frames.shm_received())
    );
    assert!(frames.try_recv_borrowed().is_none());
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_bus_clock_is_moved_by_the_clock_topic_before_the_messages_after_it() {
    use crate::msg::std_msgs::{ClockTime, Text};
    let (router, endpoint) = crate::router::open_router("tcp/127.0.0.1:0").await.unwrap();
    let ns = format!("unit-clock-{}", std::process::id());
    let args = ConnectArgs::to_router(&endpoint, &ns);
    let a = Bus::open(&args, "unit-replay").await.unwrap();
    let options = BusOptions {
        announce: true,
        clock: Clock::virtual_unset(),
        ..Default::default()
    };
    let b = Bus::open_with(&args, "unit-follower", options)
        .await
        .unwrap();
    let _follow = b.follow_clock().await.unwrap();
    let text = b.subscriber(&topics::CHATTER).await.unwrap();
    let clock = a.publisher(&topics::CLOCK).await.unwrap();
    let chatter = a.publisher(&topics::CHATTER).await.unwrap();
    tokio::time::sleep(Duration::from_millis(300)).await;
    assert!(!b.clock().is_started());
    for i in 1..=50i64 {
        let t = 1_700_000_000_000_000_000 + i * 1_000_000;
        clock
            .publish(&mut ClockTime {
                time_ns: t,
                ..Default::default()
            })
            .await
            .unwrap();
        chatter
            .publish(&mut Text {
                text: t.to_string(),
                ..Default::default()
            })
            .await
            .unwrap();
    }
    for _ in 1..=50 {
        let m = tokio::time::timeout(Duration::from_secs(10), text.recv())
            .await
            .unwrap()
            .unwrap();
        let t: i64 = m.text.parse().unwrap();
        assert!(
            b.clock().now_ns() >= t,
            "a message sent after the clock said {t} finds the clock there"
        );
    }
    assert_eq!(b.clock().now_ns(), 1_700_000_000_050_000_000);
    drop(router);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn relay_forwards_the_same_bytes_and_the_queue_drops_the_oldest() {
    let (_router, a, b) = two_buses().await;
    let frames = b
        .subscriber_named::<RgbdFrame>(topics::BENCH_FRAME.name(), 2)
        .await
        .unwrap();
    let back = a.subscriber(&topics::BENCH_FRAME_BACK).await.unwrap();
    let publisher = a.publisher(&topics::BENCH_FRAME).await.unwrap();
    let relay = b.publisher(&topics::BENCH_FRAME_BACK).await.unwrap();
    tokio::time::sleep(Duration::from_millis(300)).await;

    // Five frames into a queue of two: the three oldest are dropped and counted.
    for tag in 0..5 {
        publisher.publish(&mut frame(tag)).await.unwrap();
    }
    let deadline = Instant::now() + Duration::from_secs(10);
    let dropped = b.counters().counter("queue_dropped/bench/frame");
    while dropped.load(Ordering::Relaxed) < 3 && Instant::now() < deadline {
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    assert_eq!(dropped.load(Ordering::Relaxed), 3);
    let newest = frames.latest_borrowed().expect("the newest frame");
    assert_eq!(newest.view().rgb[0], 4);
    assert_eq!(newest.view().header.seq, 4);

    // Relayed as it is: the same payload, header untouched; an owned subscriber decodes it.
    relay.relay(&newest).await.unwrap();
    let echoed = tokio::time::timeout(Duration::from_secs(10), back.recv())
        .await
        .unwrap()
        .unwrap();
    assert_eq!(echoed, newest.to_message().unwrap());

    // publish_view: stamped by this publisher, same bytes as the owned frame otherwise.
    let mut view = newest.view();
    relay.publish_view(&mut view).await.unwrap();
    let again = tokio::time::timeout(Duration::from_secs(10), back.recv())
        .await
        .unwrap()
        .unwrap();
    assert_eq!(
        again.header.seq, 0,
        "stamped by the relay (relay() stamps nothing)"
    );
    assert_eq!(again.rgb, echoed.rgb);
    assert_eq!(again.depth_mm, echoed.depth_mm);
}

/// A router and a bus on it per name, in a namespace of their own.
async fn buses(tag: &str, names: &[&str]) -> (zenoh::Session, Vec<Bus>) {
    let (router, endpoint) = crate::router::open_router("tcp/127.0.0.1:0").await.unwrap();
    let ns = format!("unit-{tag}-{}", std::process::id());
    let args = ConnectArgs::to_router(&endpoint, &ns);
    let mut v = Vec::new();
    for n in names {
        v.push(Bus::open(&args, n).await.unwrap());
    }
    (router, v)
}

/// Calls `echo` until it answers (at most 10 s): the service's queryable is known to `bus`'
/// session. The handler must let one request through.
async fn reach_echo(bus: &Bus) {
    let req = crate::msg::std_msgs::Text {
        text: "warm-up".into(),
        ..Default::default()
    };
    let until = std::time::Instant::now() + Duration::from_secs(10);
    while let Err(e) = bus.call(&topics::ECHO, &req, Duration::from_secs(5)).await {
        assert!(
            std::time::Instant::now() < until,
            "the service never answered: {e}"
        );
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
}

/// Waits (at most 10 s) until counter `name` of `bus` reaches `n`.
async fn counted(bus: &Bus, name: &str, n: u64) {
    let until = std::time::Instant::now() + Duration::from_secs(10);
    while bus.counters().counter(name).load(Ordering::Relaxed) < n {
        assert!(
            std::time::Instant::now() < until,
            "{name} never reached {n}: {:?}",
            bus.counters().snapshot()
        );
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
}

/// A caller flooding a service waits behind its own requests only: past its share it is told
/// the service is busy (counted per caller), and another caller's requests are served in turn
/// with the flood's, not after its whole queue.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_flooding_caller_delays_only_itself() {
    use crate::msg::std_msgs::Text;
    let (_router, b) = buses("fair", &["unit-server", "unit-flood", "unit-game"]).await;
    let (server, flood, game) = (b[0].clone(), b[1].clone(), b[2].clone());
    let gate = Arc::new(tokio::sync::Semaphore::new(0));
    let entered = Arc::new(AtomicU64::new(0));
    let served: Arc<Mutex<Vec<String>>> = Arc::default();
    let _served = {
        let (gate, entered, served) = (gate.clone(), entered.clone(), served.clone());
        server
            .serve(&topics::ECHO, move |req: Text| {
                let (gate, entered, served) = (gate.clone(), entered.clone(), served.clone());
                async move {
                    entered.fetch_add(1, Ordering::Relaxed);
                    gate.acquire().await.unwrap().forget();
                    served.lock().unwrap().push(req.text.clone());
                    Ok(req)
                }
            })
            .await
            .unwrap()
    };
    let mut calls = tokio::task::JoinSet::new();
    let call = |calls: &mut tokio::task::JoinSet<_>, bus: &Bus, text: String| {
        let bus = bus.clone();
        calls.spawn(async move {
            let req = Text {
                text,
                ..Default::default()
            };
            (
                req.text.clone(),
                bus.call(&topics::ECHO, &req, Duration::from_secs(30)).await,
            )
        });
    };
    let slots = service::MAX_IN_FLIGHT;
    let share = PER_CALLER_QUEUE;
    // Both callers reach the service (its queryable is known to their sessions).
    gate.add_permits(2);
    reach_echo(&flood).await;
    reach_echo(&game).await;
    served.lock().unwrap().clear();
    let warm = entered.load(Ordering::Relaxed);
    // The flood takes every handling slot, then fills its queue and is refused 8 times.
    for i in 0..slots {
        call(&mut calls, &flood, format!("flood {i}"));
    }
    let until = std::time::Instant::now() + Duration::from_secs(10);
    while entered.load(Ordering::Relaxed) < warm + slots as u64 {
        assert!(std::time::Instant::now() < until, "the slots never filled");
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    for i in slots..slots + share + 8 {
        call(&mut calls, &flood, format!("flood {i}"));
    }
    counted(
        &server,
        &format!("service_busy/echo/{}", flood.component()),
        8,
    )
    .await;
    // The game fills a queue of its own behind all that (and is refused once).
    for i in 0..=share {
        call(&mut calls, &game, format!("game {i}"));
    }
    counted(
        &server,
        &format!("service_busy/echo/{}", game.component()),
        1,
    )
    .await;
    gate.add_permits(slots + 2 * share);
    let mut refused = BTreeMap::<String, usize>::new();
    while let Some(r) = calls.join_next().await {
        let (text, r) = r.unwrap();
        match r {
            Ok(rep) => assert_eq!(rep.text, text),
            Err(CallError::Remote(e)) if e.code == ErrorCode::Refused => {
                assert!(e.message.starts_with("busy"), "{e:?}");
                let who = text.split(' ').next().unwrap_or("").to_string();
                *refused.entry(who).or_default() += 1;
            }
            Err(e) => panic!("{text}: {e}"),
        }
    }
    assert_eq!(
        refused,
        BTreeMap::from([("flood".to_string(), 8), ("game".to_string(), 1)])
    );
    // Served in turn: the game's first request right after the requests being handled when it
    // came (give or take the handlers' own races), not after the flood's 32 queued before it.
    let order = served.lock().unwrap().clone();
    assert_eq!(order.len(), slots + 2 * share);
    let first_game = order.iter().position(|t| t.starts_with("game")).unwrap();
    assert!(
        first_game < slots + share,
        "the game's first request was served {first_game}th, after the flood's queue: {order:?}"
    );
}

/// A request whose caller stopped waiting is not handled when its turn comes: counted as
/// expired, never answered late.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_request_whose_caller_gave_up_is_dropped_not_answered_late() {
    use crate::msg::std_msgs::Text;
    let (_router, b) = buses("expired", &["unit-server", "unit-client"]).await;
    let (server, client) = (b[0].clone(), b[1].clone());
    let gate = Arc::new(tokio::sync::Semaphore::new(0));
    let served: Arc<Mutex<Vec<String>>> = Arc::default();
    let _served = {
        let (gate, served) = (gate.clone(), served.clone());
        server
            .serve(&topics::ECHO, move |req: Text| {
                let (gate, served) = (gate.clone(), served.clone());
                async move {
                    gate.acquire().await.unwrap().forget();
                    served.lock().unwrap().push(req.text.clone());
                    Ok(req)
                }
            })
            .await
            .unwrap()
    };
    gate.add_permits(1);
    reach_echo(&client).await;
    served.lock().unwrap().clear();
    // Every slot taken by patient requests.
    let mut patient = tokio::task::JoinSet::new();
    for i in 0..service::MAX_IN_FLIGHT {
        let client = client.clone();
        patient.spawn(async move {
            let req = Text {
                text: format!("patient {i}"),
                ..Default::default()
            };
            client
                .call(&topics::ECHO, &req, Duration::from_secs(30))
                .await
        });
    }
    tokio::time::sleep(Duration::from_millis(300)).await;
    // One that gives up after 300 ms, waiting behind them.
    let req = Text {
        text: "hasty".into(),
        ..Default::default()
    };
    match client
        .call(&topics::ECHO, &req, Duration::from_millis(300))
        .await
    {
        Err(CallError::Timeout { .. }) => {}
        other => panic!("expected a time-out, got {other:?}"),
    }
    gate.add_permits(service::MAX_IN_FLIGHT + 1);
    while let Some(r) = patient.join_next().await {
        r.unwrap().unwrap();
    }
    let expired = format!("service_expired/echo/{}", client.component());
    counted(&server, &expired, 1).await;
    assert!(
        !served.lock().unwrap().iter().any(|t| t == "hasty"),
        "the hasty request was handled after its caller gave up"
    );
}

/// A reader that joins late asks for what was published while it was away: the samples after
/// its mark, oldest first, only those within the publisher's window; none when nothing keeps
/// them.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_late_reader_catches_up_on_the_recent_samples_and_no_older() {
    use crate::msg::speech::AudioChunk;
    let (_router, a, b) = two_buses().await;
    let t = Duration::from_secs(5);
    assert!(
        b.recent(&topics::AUDIO_IN, 0, Duration::from_millis(300))
            .await
            .unwrap()
            .is_empty()
    );
    let mic = a
        .recent_publisher(&topics::AUDIO_IN, Duration::from_millis(250))
        .await
        .unwrap();
    // Chunks stamped 100 ms apart (their stamps are the publisher's clock, here set).
    for i in 1..=6i64 {
        let mut c = AudioChunk::mono(16_000, &[i as i16; 160]);
        c.header.stamp_ns = i * 100_000_000;
        mic.publish(&mut c).await.unwrap();
    }
    // The window keeps 250 ms behind the newest: chunks 4, 5 and 6 (3 is 300 ms behind). The
    // publisher's queryable reaches the other session through the router a moment after it is
    // declared: asked until it answers.
    let deadline = std::time::Instant::now() + t;
    let all = loop {
        let all = b.recent(&topics::AUDIO_IN, 0, t).await.unwrap();
        if !all.is_empty() || std::time::Instant::now() > deadline {
            break all;
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    };
    let stamps: Vec<i64> = all
        .iter()
        .map(|c| c.header.stamp_ns / 100_000_000)
        .collect();
    assert_eq!(stamps, [4, 5, 6]);
    assert_eq!(
        all[2].samples().unwrap(),
        vec![6i16; 160],
        "the same samples"
    );
    // After a mark: only what is newer.
    let after = b.recent(&topics::AUDIO_IN, 500_000_000, t).await.unwrap();
    assert_eq!(after.len(), 1);
    assert_eq!(after[0].header.stamp_ns, 600_000_000);
    // A publisher gone keeps nothing for anyone.
    drop(mic);
    assert!(
        b.recent(&topics::AUDIO_IN, 0, Duration::from_millis(300))
            .await
            .unwrap()
            .is_empty()
    );
}
