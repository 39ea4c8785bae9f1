//! A real V4L2 camera (a UVC webcam), named by `PENELOPE_CAMERA` (`/dev/video0`): opened with the
//! default settings (640x480 at 30 fps, MJPEG preferred), 60 frames captured, their rate checked
//! against the negotiated one, their capture instants against their dequeue times, and every
//! JPEG decoded. Without `PENELOPE_CAMERA` it says it was not run and why (scripts/test reports
//! it as not run in its summary):
//!
//! ```sh
//! PENELOPE_CAMERA=/dev/video0 cargo test --release -p penelope-drivers --test v4l2_device -- --nocapture
//! ```

use std::time::Duration;

use penelope_drivers::v4l2::{V4l2Camera, V4l2Error, V4l2Settings};

const FRAMES: usize = 60;

#[test]
fn a_real_v4l2_camera_streams_stamped_decodable_frames() {
    let Some(device) = std::env::var_os("PENELOPE_CAMERA") else {
        eprintln!(
            "v4l2_device: NOT RUN: no camera named (set PENELOPE_CAMERA=/dev/videoN to run it \
             against a V4L2 device)"
        );
        return;
    };
    let settings = V4l2Settings::new(device);
    let mut camera = V4l2Camera::open(&settings).unwrap_or_else(|e| panic!("open: {e}"));
    let negotiated = camera.negotiated();
    eprintln!("{:?}: {negotiated}", camera.identity());

    let mut frames = Vec::with_capacity(FRAMES);
    let mut garbled = 0;
    while frames.len() < FRAMES {
        match camera.next(Duration::from_secs(2)) {
            Ok(frame) => frames.push(frame),
            Err(e @ V4l2Error::Garbled { .. }) => {
                eprintln!("{e}");
                garbled += 1;
                assert!(
                    garbled <= 3,
                    "more than 3 garbled frames: {:?}",
                    camera.stats()
                );
            }
            Err(e) => panic!("after {} frames: {e}", frames.len()),
        }
    }
    let stats = camera.stats();
    eprintln!("{stats:?}");
    // Stop streaming before the checks (without the `v4l2` feature no camera opens at all).
    #[allow(clippy::drop_non_drop)]
    drop(camera);

    // The camera's own rate: driver frames (sequence numbers) over capture time, so that frames
    // this reader dropped do not count against it.
    let (first, last) = (&frames[0], &frames[FRAMES - 1]);
    let span_s = (last.capture_ns - first.capture_ns) as f64 / 1e9;
    let rate = f64::from(last.sequence - first.sequence) / span_s;
    eprintln!(
        "measured {rate:.2} fps over {span_s:.2} s; negotiated {:?}; timestamp source of the last: {}",
        negotiated.rate_hz,
        last.timestamp_source.name()
    );
    if let Some(expected) = negotiated.rate_hz {
        // Loose: a UVC camera in dim light lengthens its exposure and can halve its rate.
        assert!(
            rate > 0.45 * expected && rate < 1.2 * expected,
            "{rate:.2} fps measured, {expected:.2} negotiated"
        );
    }

    let mut worst_delay_ns = 0;
    for pair in frames.windows(2) {
        assert!(
            pair[1].capture_ns > pair[0].capture_ns,
            "capture instants not increasing: {} then {}",
            pair[0].capture_ns,
            pair[1].capture_ns
        );
    }
    for f in &frames {
        // the capture instant precedes its dequeue (1 ms for the clock reads) by at most 200 ms
        assert!(
            f.capture_ns <= f.dequeued_ns + 1_000_000,
            "frame {} captured after its dequeue",
            f.sequence
        );
        let delay = f.dequeued_ns.saturating_sub(f.capture_ns);
        assert!(delay <= 200_000_000, "frame {}: {delay} ns", f.sequence);
        worst_delay_ns = worst_delay_ns.max(delay);
        assert_eq!((f.width, f.height), (negotiated.width, negotiated.height));
        let mut decoder = zune_jpeg::JpegDecoder::new(&f.jpeg);
        decoder
            .decode()
            .unwrap_or_else(|e| panic!("frame {}: {e:?}", f.sequence));
        assert_eq!(
            decoder.dimensions(),
            Some((f.width as usize, f.height as usize)),
            "frame {}",
            f.sequence
        );
    }
    eprintln!(
        "worst capture-to-dequeue {:.1} ms; {} garbled",
        worst_delay_ns as f64 / 1e6,
        garbled
    );
}
