//! The alignment's tests: histories, figures, meters and projections.

use super::*;

const MS: u64 = 1_000_000;

fn sample(time_ns: u64, fx: f64) -> ForceSample {
    ForceSample {
        time_ns,
        tool_position: [fx * 0.01, 0.0, 0.5],
        wrench: WrenchMsg {
            force: [fx, 0.0, 0.0],
            torque: [0.0; 3],
        },
    }
}

/// A force that changes every instant, so that a sample taken at the wrong time shows.
fn force_at(t_ns: u64) -> f64 {
    (t_ns as f64 * 1e-9 * 7.0).sin() * 10.0
}

/// Samples every `period`, frames every 33 ms whose arrival is 20 ms after capture: the
/// aligned residual skew stays under a sample period (far under a frame period), the
/// unaligned skew shows the 20 ms.
fn delayed_frames(period_ns: u64) -> (SyncSummary, f64) {
    let mut history = SampleHistory::default();
    let mut meter = SyncMeter::default();
    let frame_period = 33 * MS;
    let delay = 20 * MS;
    // Captures fall between samples (0.4 ms past a whole millisecond).
    let mut next_capture = 100 * MS + 400_000;
    let mut worst_force_error = 0.0f64;
    // The clock runs in 1 ms steps; the robot's samples come every `period_ns`.
    for t in (0..3_000 * MS).step_by(MS as usize) {
        if t % period_ns == 0 {
            history.push(sample(t, force_at(t)));
        }
        // The frame captured 20 ms ago arrives now.
        if t >= next_capture + delay {
            let capture = next_capture;
            let aligned = history.at(capture).unwrap();
            let newest = history.newest_for(capture).unwrap();
            // The hand feels (on one node) the newest sample's force.
            let hand = newest.sample.time_ns;
            worst_force_error =
                worst_force_error.max((aligned.sample.wrench.force[0] - force_at(capture)).abs());
            meter.observe(&FrameFigures::of(
                t,
                capture,
                Some(hand),
                Some(&aligned),
                Some(&newest),
            ));
            next_capture += frame_period;
        }
    }
    (meter.summary(), worst_force_error)
}

#[test]
fn frames_delayed_20ms_align_within_a_frame_period_while_the_newest_sample_is_20ms_off() {
    for period in [MS, 10 * MS] {
        let (summary, force_error) = delayed_frames(period);
        let aligned = summary.aligned_skew.unwrap();
        let unaligned = summary.unaligned_skew.unwrap();
        let skew = summary.operator_skew.unwrap();
        println!(
            "samples every {} ms: aligned residual skew p50 {} p99 {} max {} ns; \
             unaligned p50 {} ns; operator skew p50 {} ns; force error {force_error:.4} N",
            period / MS,
            aligned.p50_ns,
            aligned.p99_ns,
            aligned.max_ns,
            unaligned.p50_ns,
            skew.p50_ns
        );
        assert!(aligned.count > 80);
        assert!(aligned.max_ns < (33 * MS) as i64);
        assert!(aligned.max_ns <= (period / 2) as i64);
        // The newest sample is the one before the frame's arrival, 20 ms after capture (to
        // the next 1 ms step of the clock).
        assert!(unaligned.p50_ns > (20 * MS - period) as i64);
        assert!(unaligned.max_ns <= (21 * MS) as i64);
        assert!(unaligned.p50_ns > 5 * aligned.p50_ns.max(MS as i64));
        assert_eq!(skew.p50_ns, unaligned.p50_ns);
        // Interpolating a 7 rad/s sine sampled every 10 ms errs by < 0.01 N of 10 N.
        assert!(force_error < 0.01, "{force_error}");
    }
}

#[test]
fn an_empty_history_gives_nothing() {
    let history = SampleHistory::default();
    assert!(history.at(5 * MS).is_none());
    assert!(history.newest_for(5 * MS).is_none());
    assert!(history.is_empty());
    let figures = FrameFigures::of(10 * MS, 5 * MS, None, None, None);
    assert_eq!(figures.video_latency_ns, 5_000_000);
    assert_eq!(figures.operator_skew_ns, None);
    let mut meter = SyncMeter::new(4);
    assert_eq!(meter.summary().video_latency, None);
    meter.observe(&figures);
    assert_eq!(meter.summary().force_latency, None);
    assert_eq!(meter.summary().video_latency.unwrap().count, 1);
}

#[test]
fn across_a_gap_the_nearest_sample_is_given_with_its_true_skew() {
    let mut history = SampleHistory::default();
    history.push(sample(0, 1.0));
    history.push(sample(10 * MS, 2.0));
    // 200 ms lost.
    history.push(sample(210 * MS, 3.0));
    let inside = history.at(5 * MS).unwrap();
    assert_eq!(inside.how, Match::Interpolated);
    assert!((inside.sample.wrench.force[0] - 1.5).abs() < 1e-12);
    assert_eq!(inside.sample.time_ns, 5 * MS);
    let gap = history.at(60 * MS).unwrap();
    assert_eq!(gap.how, Match::Nearest);
    assert_eq!(gap.sample.wrench.force[0], 2.0);
    assert_eq!(gap.skew_ns, -50_000_000);
    let late = history.at(190 * MS).unwrap();
    assert_eq!((late.how, late.skew_ns), (Match::Nearest, 20_000_000));
    // A frame newer than every sample: the newest, measured before it.
    let ahead = history.at(230 * MS).unwrap();
    assert_eq!((ahead.how, ahead.skew_ns), (Match::Newest, -20_000_000));
    // Exactly on a sample.
    let on = history.at(10 * MS).unwrap();
    assert_eq!((on.how, on.skew_ns), (Match::Interpolated, 0));
    assert_eq!(on.sample.wrench.force[0], 2.0);
}

#[test]
fn out_of_order_samples_take_their_place_and_stale_or_bad_ones_are_refused() {
    let mut history = SampleHistory::new(Duration::from_millis(100), 1000);
    assert_eq!(history.push(sample(20 * MS, 2.0)), Admission::Added);
    assert_eq!(history.push(sample(40 * MS, 4.0)), Admission::Added);
    assert_eq!(history.push(sample(30 * MS, 3.0)), Admission::Reordered);
    assert_eq!(history.push(sample(30 * MS, 3.5)), Admission::Replaced);
    let times: Vec<u64> = history.iter().map(|s| s.time_ns / MS).collect();
    assert_eq!(times, [20, 30, 40]);
    assert_eq!(history.at(30 * MS).unwrap().sample.wrench.force[0], 3.5);
    // 150 ms behind the newest, past the 100 ms span.
    assert_eq!(history.push(sample(140 * MS, 14.0)), Admission::Added);
    assert_eq!(history.oldest().unwrap().time_ns, 40 * MS);
    assert_eq!(history.push(sample(10 * MS, 1.0)), Admission::Stale);
    assert_eq!(
        history.push(sample(150 * MS, f64::NAN)),
        Admission::NotFinite
    );
    assert_eq!(history.len(), 2);
    // A frame older than the history reaches: the oldest, and how far it is.
    let old = history.at(15 * MS).unwrap();
    assert_eq!((old.how, old.skew_ns), (Match::Oldest, 25_000_000));
}

#[test]
fn the_history_is_bounded_in_count_and_span() {
    let mut history = SampleHistory::new(Duration::from_secs(2), 100);
    for k in 0..10_000u64 {
        history.push(sample(k * MS, k as f64));
    }
    assert_eq!(history.len(), 100);
    assert_eq!(history.oldest().unwrap().time_ns, 9_900 * MS);
    let mut history = SampleHistory::new(Duration::from_millis(50), 100_000);
    for k in 0..10_000u64 {
        history.push(sample(k * MS, k as f64));
    }
    assert_eq!(history.len(), 51);
}

#[test]
fn the_hand_feels_a_force_measured_one_trip_before_the_masters_tick() {
    assert_eq!(force_measured_ns(100 * MS, Some(3_000_000)), 97 * MS);
    assert_eq!(force_measured_ns(100 * MS, None), 100 * MS);
    assert_eq!(force_measured_ns(MS, Some(5_000_000)), 0);
    // Display at 200 ms of a frame captured at 120 ms, hand's force measured at 190 ms.
    let f = FrameFigures::of(200 * MS, 120 * MS, Some(190 * MS), None, None);
    assert_eq!(f.video_latency_ns, 80_000_000);
    assert_eq!(f.force_latency_ns, Some(10_000_000));
    assert_eq!(f.operator_skew_ns, Some(70_000_000));
    assert_eq!(describe_skew(70_000_000), "video 70 ms behind the hand");
    assert_eq!(describe_skew(-3_000_000), "video 3 ms ahead of the hand");
    assert_eq!(describe_skew(100_000), "video in step with the hand");
    assert_eq!(to_common(5, -10), 0);
    assert_eq!(to_common(5, 10), 15);
}

#[test]
fn percentiles_by_nearest_rank_over_a_bounded_window() {
    let p = Percentiles::of((1..=100).rev()).unwrap();
    assert_eq!((p.p50_ns, p.p99_ns, p.max_ns, p.count), (50, 99, 100, 100));
    assert_eq!(Percentiles::of([7]).unwrap().p99_ns, 7);
    let mut meter = SyncMeter::new(10);
    for k in 0..1000 {
        meter.observe(&FrameFigures::of(k + 5, k, None, None, None));
    }
    let v = meter.summary().video_latency.unwrap();
    assert_eq!((v.count, v.max_ns), (10, 5));
}

#[test]
fn a_point_projects_where_the_pinhole_puts_it() {
    // A camera 2 m out along base x, looking back at the origin (z toward -x), image x
    // along base y, image y down (base -z).
    let model = CameraModelMsg {
        frame_id: "cam".into(),
        width: 640,
        height: 480,
        fx: 500.0,
        fy: 500.0,
        cx: 320.0,
        cy: 240.0,
        pose_in_robot_base: Some(PoseMsg {
            position: [2.0, 0.0, 0.0],
            n: [0.0, 1.0, 0.0],
            o: [0.0, 0.0, -1.0],
            a: [-1.0, 0.0, 0.0],
        }),
        robot: Some("slave".into()),
    };
    assert_eq!(project(&model, [0.0, 0.0, 0.0]), Some([320.0, 240.0]));
    // 0.2 m along base y at 2 m depth: 50 px right; 0.2 m up: 50 px up.
    assert_eq!(project(&model, [0.0, 0.2, 0.2]), Some([370.0, 190.0]));
    assert_eq!(project(&model, [3.0, 0.0, 0.0]), None);
    let s = ForceSample {
        time_ns: 0,
        tool_position: [0.0; 3],
        wrench: WrenchMsg {
            force: [0.0, 3.0, 4.0],
            torque: [0.0; 3],
        },
    };
    let arrow = force_arrow(&model, &s, 0.01).unwrap();
    assert_eq!(arrow.magnitude_n, 5.0);
    assert_eq!(arrow.tool_px, [320.0, 240.0]);
    assert!((arrow.tip_px[0] - 327.5).abs() < 1e-9 && (arrow.tip_px[1] - 230.0).abs() < 1e-9);
    let unplaced = CameraModelMsg {
        pose_in_robot_base: None,
        ..model
    };
    assert_eq!(force_arrow(&unplaced, &s, 0.01), None);
    // A tool turned a quarter turn about base z: its x is base y.
    let turned = PoseMsg {
        position: [0.0; 3],
        n: [0.0, 1.0, 0.0],
        o: [-1.0, 0.0, 0.0],
        a: [0.0, 0.0, 1.0],
    };
    assert_eq!(tool_to_base([2.0, 0.0, 5.0], &turned), [0.0, 2.0, 5.0]);
}
