use std::collections::BTreeSet;

use proptest::prelude::*;

use super::*;

const MS: Duration = Duration::from_millis(1);
const US: Duration = Duration::from_micros(1);

/// Sends items `0..count`, one every `period`, polling every `step` until everything left;
/// returns `(item, sent at, delivered at)` in delivery order.
fn run(
    link: &mut FaultyLink<u32>,
    count: u32,
    period: Duration,
    step: Duration,
) -> Vec<(u32, Duration, Duration)> {
    let mut delivered = Vec::new();
    let mut now = Duration::ZERO;
    let mut next = 0u32;
    let mut next_send = Duration::ZERO;
    while next < count || link.in_flight() > 0 {
        while next < count && next_send <= now {
            link.send(now, next);
            next += 1;
            next_send += period;
        }
        while let Some(item) = link.poll(now) {
            delivered.push((item, period * item, now));
        }
        now += step;
    }
    delivered
}

fn link(config: &FaultConfig, seed: u64) -> FaultyLink<u32> {
    FaultyLink::new(config, seed, 100_000).unwrap()
}

#[test]
fn without_faults_everything_passes_at_once_and_in_order() {
    let mut link = link(&FaultConfig::default(), 1);
    for i in 0..1_000 {
        let now = MS * i;
        link.send(now, i);
        assert_eq!(link.poll(now), Some(i));
        assert_eq!(link.poll(now), None);
    }
    // a burst at one instant comes out in the order it went in
    let now = Duration::from_secs(2);
    (0..100).for_each(|i| link.send(now, i));
    let burst: Vec<u32> = std::iter::from_fn(|| link.poll(now)).collect();
    assert_eq!(burst, (0..100).collect::<Vec<_>>());
    let counters = link.counters();
    assert_eq!((counters.sent, counters.delivered), (1_100, 1_100));
    assert_eq!(
        counters.dropped_loss + counters.dropped_outage + counters.duplicated,
        0
    );
}

#[test]
fn one_percent_loss_is_within_statistical_bounds() {
    let config = FaultConfig {
        loss: 0.01,
        ..FaultConfig::default()
    };
    let mut link = link(&config, 7);
    let delivered = run(&mut link, 100_000, MS, MS);
    let lost = link.counters().dropped_loss;
    // binomial(100000, 0.01): mean 1000, standard deviation 31.5; allow 5 sigma
    eprintln!("1% loss over 100000 items: {lost} lost");
    assert!((843..=1157).contains(&lost), "{lost} lost");
    assert_eq!(delivered.len() as u64, 100_000 - lost);
    // the survivors still in order, none twice
    assert!(delivered.windows(2).all(|w| w[0].0 < w[1].0));
}

#[test]
fn an_outage_drops_exactly_the_items_sent_in_it() {
    let config = FaultConfig::from_toml(
        "delay_ms = 3.0\noutages = [{ from_s = 1.0, to_s = 2.0 }, { from_s = 3.5, to_s = 3.6 }]",
    )
    .unwrap();
    let mut link = link(&config, 3);
    let delivered = run(&mut link, 5_000, MS, MS);
    let received: BTreeSet<u32> = delivered.iter().map(|d| d.0).collect();
    let expected: BTreeSet<u32> = (0..5_000)
        .filter(|i| !(1_000..2_000).contains(i) && !(3_500..3_600).contains(i))
        .collect();
    assert_eq!(received, expected);
    assert_eq!(link.counters().dropped_outage, 1_100);
    // items sent just before a window, still in flight in it, arrive
    assert!(received.contains(&999) && received.contains(&3_499));
}

#[test]
fn delay_and_jitter_bound_every_latency() {
    let config = FaultConfig {
        delay_ms: 5.0,
        jitter_ms: 2.0,
        loss: 0.05,
        duplicate: 0.05,
        ..FaultConfig::default()
    };
    let mut link = link(&config, 11);
    let step = 10 * US;
    let delivered = run(&mut link, 10_000, MS, step);
    let latencies: Vec<Duration> = delivered.iter().map(|&(_, sent, at)| at - sent).collect();
    let (least, most) = (
        latencies.iter().min().unwrap(),
        latencies.iter().max().unwrap(),
    );
    eprintln!("delay 5 ms + jitter 2 ms: latency from {least:?} to {most:?}");
    assert!(*least >= 5 * MS);
    assert!(*most < 7 * MS + step, "{most:?}");
    // the jitter is spread over its whole range
    assert!(*least < 5 * MS + 100 * US && *most > 7 * MS - 100 * US);
    // jitter wider than the send period reorders some items by itself
    assert!(delivered.windows(2).any(|w| w[0].0 > w[1].0));
    let counters = link.counters();
    assert!(counters.duplicated > 0);
    assert_eq!(
        counters.delivered,
        counters.sent - counters.dropped_loss + counters.duplicated
    );
}

#[test]
fn reordering_holds_an_item_past_the_next() {
    let config = FaultConfig {
        reorder: 0.1,
        ..FaultConfig::default()
    };
    let mut link = link(&config, 5);
    let delivered = run(&mut link, 10_000, MS, 100 * US);
    let order: Vec<u32> = delivered.iter().map(|d| d.0).collect();
    // everything arrives, once
    assert_eq!(order.iter().copied().collect::<BTreeSet<_>>().len(), 10_000);
    let overtaken = order.windows(2).filter(|w| w[0] > w[1]).count() as u64;
    let reordered = link.counters().reordered;
    eprintln!("reorder 0.1 over 10000 items: {reordered} held back past the next");
    // a share p / (1 + p) = 9.1% of the stream is held back
    assert!((750..=1_070).contains(&reordered), "{reordered}");
    assert_eq!(overtaken, reordered);
    // a held item waits for the next one only so long: the last one comes out anyway
    let mut lonely = FaultyLink::new(
        &FaultConfig {
            reorder: 1.0,
            ..FaultConfig::default()
        },
        0,
        8,
    )
    .unwrap();
    lonely.send(Duration::ZERO, 42);
    assert_eq!(lonely.poll(Duration::ZERO), None);
    assert_eq!(lonely.next_release(), Some(REORDER_HOLD_LIMIT));
    assert_eq!(lonely.poll(REORDER_HOLD_LIMIT), Some(42));
    assert_eq!(lonely.counters().reordered, 0);
}

#[test]
fn the_same_seed_gives_the_same_faults_and_different_seeds_differ() {
    let config = FaultConfig {
        delay_ms: 1.0,
        jitter_ms: 3.0,
        loss: 0.02,
        duplicate: 0.02,
        reorder: 0.05,
        outages: vec![OutageWindow {
            from_s: 0.5,
            to_s: 0.6,
        }],
        clock_offset_us: 0.0,
    };
    let outcome = |seed| {
        let mut link = link(&config, seed);
        let delivered = run(&mut link, 2_000, MS, 100 * US);
        (delivered, link.counters())
    };
    assert_eq!(outcome(1), outcome(1));
    assert_ne!(outcome(1).0, outcome(2).0);
    assert_ne!(outcome(1).1, outcome(2).1);
}

#[test]
fn items_beyond_capacity_are_dropped_and_counted() {
    let config = FaultConfig {
        delay_ms: 10.0,
        ..FaultConfig::default()
    };
    let mut link = FaultyLink::new(&config, 0, 4).unwrap();
    (0..10).for_each(|i| link.send(Duration::ZERO, i));
    assert_eq!(link.in_flight(), 4);
    assert_eq!(link.counters().dropped_capacity, 6);
    assert_eq!(link.next_release(), Some(10 * MS));
    assert_eq!(link.poll(9 * MS), None);
    let out: Vec<u32> = std::iter::from_fn(|| link.poll(10 * MS)).collect();
    assert_eq!(out, vec![0, 1, 2, 3]);
    assert_eq!(link.next_release(), None);
}

#[test]
fn configurations_parse_from_toml_and_bad_ones_name_their_key() {
    let config = FaultConfig::from_toml(
        "delay_ms = 2.0\njitter_ms = 5.0\nloss = 0.01\nduplicate = 0.001\nreorder = 0.01\n\
         outages = [{ from_s = 10.0, to_s = 12.5 }]\nclock_offset_us = -3700.0",
    )
    .unwrap();
    assert_eq!(
        config,
        FaultConfig {
            delay_ms: 2.0,
            jitter_ms: 5.0,
            loss: 0.01,
            duplicate: 0.001,
            reorder: 0.01,
            outages: vec![OutageWindow {
                from_s: 10.0,
                to_s: 12.5
            }],
            clock_offset_us: -3700.0,
        }
    );
    assert_eq!(config.clock_offset_ns(), -3_700_000);
    assert_eq!(FaultConfig::from_toml("").unwrap(), FaultConfig::default());

    let key_of = |text: &str| match FaultConfig::from_toml(text).unwrap_err() {
        FaultConfigError::OutOfRange { key, .. } | FaultConfigError::EmptyOutage { key, .. } => key,
        FaultConfigError::Parse { message } => message,
    };
    assert_eq!(key_of("loss = 1.5"), "loss");
    assert_eq!(key_of("duplicate = -0.1"), "duplicate");
    assert_eq!(key_of("reorder = nan"), "reorder");
    assert_eq!(key_of("delay_ms = -1.0"), "delay_ms");
    assert_eq!(key_of("jitter_ms = inf"), "jitter_ms");
    assert_eq!(key_of("clock_offset_us = 2e7"), "clock_offset_us");
    assert_eq!(key_of("clock_offset_us = nan"), "clock_offset_us");
    assert_eq!(
        key_of("outages = [{ from_s = 1.0, to_s = 2.0 }, { from_s = -1.0, to_s = 2.0 }]"),
        "outages[1].from_s"
    );
    assert_eq!(
        key_of("outages = [{ from_s = 3.0, to_s = 2.0 }]"),
        "outages[0]"
    );
    // unknown keys and wrong units are refused by the parser, which names them
    assert!(key_of("delay = 2.0").contains("delay"));
    assert!(key_of("outages = [{ from_s = 1.0, to_ms = 2.0 }]").contains("to_ms"));
    assert!(key_of("loss = \"1%\"").contains("loss"));
    // the link refuses what validation refuses
    let bad = FaultConfig {
        loss: 2.0,
        ..FaultConfig::default()
    };
    assert!(matches!(
        FaultyLink::<u32>::new(&bad, 0, 1),
        Err(FaultConfigError::OutOfRange { .. })
    ));
}

/// A valid configuration with every fault possible.
fn config() -> impl Strategy<Value = FaultConfig> {
    (
        0.0..50.0f64,
        0.0..50.0f64,
        0.0..=1.0f64,
        0.0..=1.0f64,
        0.0..=1.0f64,
        prop::collection::vec((0.0..10.0f64, 0.001..5.0f64), 0..3),
    )
        .prop_map(
            |(delay_ms, jitter_ms, loss, duplicate, reorder, windows)| FaultConfig {
                delay_ms,
                jitter_ms,
                loss,
                duplicate,
                reorder,
                outages: windows
                    .into_iter()
                    .map(|(from_s, length_s)| OutageWindow {
                        from_s,
                        to_s: from_s + length_s,
                    })
                    .collect(),
                clock_offset_us: 0.0,
            },
        )
}

proptest! {
    #[test]
    fn every_item_is_accounted_for(
        config in config(),
        seed in any::<u64>(),
        capacity in 0usize..64,
        ops in prop::collection::vec((any::<bool>(), 0u64..20_000), 0..300),
    ) {
        let mut link = FaultyLink::new(&config, seed, capacity).unwrap();
        let mut now = Duration::ZERO;
        for (is_send, advance_us) in ops {
            now += US * advance_us as u32;
            if is_send {
                link.send(now, 0u8);
            } else {
                while link.poll(now).is_some() {}
            }
            prop_assert!(link.in_flight() <= capacity);
            let c = link.counters();
            prop_assert_eq!(
                c.sent + c.duplicated,
                c.dropped_loss + c.dropped_outage + c.dropped_capacity + c.delivered
                    + link.in_flight() as u64
            );
        }
    }
}
