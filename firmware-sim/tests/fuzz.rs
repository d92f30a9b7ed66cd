//! A seeded mutation fuzzer against the firmware: valid frames of every request, mutated
//! (bit flips, byte insertions and deletions, truncation, random bytes, zero-length and
//! oversized frames, other versions, unknown variants), fed through `serve` in long streams.
//! No input may panic it or leave it stuck: after every batch, a resynchronising delimiter,
//! `Hello` and `Status` must be answered as on a fresh link.
//!
//! `DIPS_FUZZ_FRAMES` sets the number of frames (default 100 000, the slice CI runs (under a second); the full
//! run is `DIPS_FUZZ_FRAMES=1000000 cargo test --release -p dips-firmware-sim --test fuzz`),
//! `DIPS_FUZZ_SEED` the seed.

mod common;

use common::frame_bytes;
use dips_firmware_sim::{FirmwareMemory, serve};
use dips_kernel::rng::KernelRng;
use dips_wire::*;

/// One valid message of every request kind (a small junk model upload included).
fn corpus() -> Vec<ToKernel> {
    let mut start = [0.1f32; 16];
    start[14] = 1.0;
    start[15] = 0.0;
    let mut v = vec![
        ToKernel::Hello(Hello::current()),
        ToKernel::Status,
        ToKernel::Cancel,
        ToKernel::PlanRequest(PlanRequest {
            task: Task::Screwdriver,
            start_state: heapless::Vec::from_slice(&start).unwrap(),
            goal: -1.0,
            settings: SearchSettings::default(),
            previous_mode: Some(1),
            card_goals: Default::default(),
            first_modes: 0b111,
        }),
        ToKernel::SetPrior(PriorTable {
            task: Task::Card,
            probabilities: heapless::Vec::from_slice(&[0.25; 20]).unwrap(),
        }),
        ToKernel::SetSampler(SamplerSettings {
            method: SamplerMethod::DdimEta {
                steps: 16,
                eta: 1.0,
            },
            guidance_weight: 1.2,
        }),
    ];
    let model: Vec<u8> = (0..1500u32).map(|i| (i * 31 % 251) as u8).collect();
    v.extend(upload_messages(ModelRole::Discriminator, &model).unwrap());
    v
}

/// Postcard bytes of a frame (the COBS layer taken off again).
fn payload(id: u32, body: &ToKernel) -> Vec<u8> {
    let framed = frame_bytes(id, body.clone());
    let mut acc = FrameAccumulator::<MAX_ENCODED_FRAME_LEN>::new();
    match acc.feed(&framed) {
        Feed::Frame { payload, .. } => payload.to_vec(),
        _ => unreachable!("a frame we encoded decodes"),
    }
}

fn cobs(bytes: &[u8]) -> Vec<u8> {
    let mut out = vec![0u8; bytes.len() + bytes.len() / 254 + 2];
    let n = cobs_encode(bytes, &mut out);
    out.truncate(n);
    out.push(0);
    out
}

/// COBS encoding (the frames' framing), written here so mutated payloads are framed validly.
fn cobs_encode(input: &[u8], out: &mut [u8]) -> usize {
    let mut code_at = 0;
    let mut o = 1;
    let mut code = 1u8;
    for &b in input {
        if b == 0 {
            out[code_at] = code;
            code_at = o;
            o += 1;
            code = 1;
        } else {
            out[o] = b;
            o += 1;
            code += 1;
            if code == 0xFF {
                out[code_at] = code;
                code_at = o;
                o += 1;
                code = 1;
            }
        }
    }
    out[code_at] = code;
    o
}

/// One mutated frame.
fn mutated(rng: &mut KernelRng, corpus: &[ToKernel]) -> Vec<u8> {
    let body = &corpus[rng.below(corpus.len() as u32) as usize];
    let id = rng.below(u32::MAX);
    let mut p = payload(id, body);
    let byte = |rng: &mut KernelRng| rng.below(256) as u8;
    match rng.below(12) {
        // Mutate the postcard payload, then frame it validly: the decoder sees it.
        0..=4 => {
            for _ in 0..=rng.below(4) {
                if p.is_empty() {
                    break;
                }
                let i = rng.below(p.len() as u32) as usize;
                match rng.below(4) {
                    0 => p[i] ^= 1 << rng.below(8),
                    1 => p[i] = byte(rng),
                    2 => p.insert(i, byte(rng)),
                    _ => {
                        p.remove(i);
                    }
                }
            }
            cobs(&p)
        }
        // Truncated.
        5 => {
            let n = rng.below(p.len() as u32 + 1) as usize;
            cobs(&p[..n])
        }
        // An unknown variant (a newer peer's), or another protocol version.
        6 => {
            let mut q = payload(id, &ToKernel::Status);
            let last = q.len() - 1;
            q[last] = 9 + rng.below(100) as u8;
            cobs(&q)
        }
        7 => cobs(&payload(
            id,
            &ToKernel::Hello(Hello {
                protocol_version: rng.below(5) as u16,
                schema_key: rng.next_u64(),
            }),
        )),
        // Random bytes, delimited.
        8 => {
            let n = rng.below(80) as usize;
            let mut r: Vec<u8> = (0..n).map(|_| byte(rng)).collect();
            r.push(0);
            r
        }
        // Zero-length frames.
        9 => vec![0; 1 + rng.below(3) as usize],
        // Oversized: longer than any frame, no delimiter inside.
        10 => {
            let n = MAX_ENCODED_FRAME_LEN + rng.below(2000) as usize;
            let mut r: Vec<u8> = (0..n).map(|_| 1 + rng.below(255) as u8).collect();
            r.push(0);
            r
        }
        // Valid framing, mutated after COBS (broken COBS, split frames).
        _ => {
            let mut f = cobs(&p);
            let i = rng.below(f.len() as u32) as usize;
            f[i] = byte(rng);
            f
        }
    }
}

fn replies(bytes: &[u8]) -> Vec<Frame<FromKernel>> {
    let mut acc = FrameAccumulator::<MAX_ENCODED_FRAME_LEN>::new();
    let mut out = Vec::new();
    let mut window = bytes;
    loop {
        match acc.feed(window) {
            Feed::Consumed => return out,
            Feed::Frame { payload, remaining } => {
                out.push(decode_frame::<FromKernel>(payload).expect("every reply decodes"));
                window = remaining;
            }
            Feed::Error { error, .. } => panic!("a reply frame is broken: {error}"),
        }
    }
}

#[test]
fn mutated_frames_never_panic_or_stick_the_firmware() {
    let frames: usize = std::env::var("DIPS_FUZZ_FRAMES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(100_000);
    let seed: u64 = std::env::var("DIPS_FUZZ_SEED")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(1);
    let corpus = corpus();
    let mut rng = KernelRng::seed_from_u64(seed);
    let mut memory = FirmwareMemory::models(4096);
    let mut firmware = memory.firmware();
    let t0 = std::time::Instant::now();
    let mut sent = 0usize;
    let mut replies_seen = 0usize;
    let batch = 5_000;
    while sent < frames {
        let n = batch.min(frames - sent);
        let mut input = Vec::new();
        for _ in 0..n {
            input.extend(mutated(&mut rng, &corpus));
        }
        // The sentinel: resynchronise, greet, ask the status.
        input.push(0);
        input.extend(frame_bytes(0xFFFF_FFF0, ToKernel::Hello(Hello::current())));
        input.extend(frame_bytes(0xFFFF_FFF1, ToKernel::Status));
        let mut out = Vec::new();
        firmware.reset_session();
        let stats = serve(&mut firmware, &input[..], &mut out).expect("serving never fails");
        let got = replies(&out);
        assert_eq!(got.len() as u64, stats.replies);
        assert_eq!(stats.replies, stats.requests + stats.bad_frames);
        let [.., hello, status] = &got[..] else {
            panic!("no sentinel replies after {sent} frames");
        };
        assert_eq!(
            hello.request_id, 0xFFFF_FFF0,
            "seed {seed}, batch at {sent}"
        );
        assert!(
            matches!(hello.body, FromKernel::HelloAck(_)),
            "{:?}",
            hello.body
        );
        assert_eq!(status.request_id, 0xFFFF_FFF1);
        let FromKernel::Status(s) = status.body else {
            panic!("{:?}", status.body);
        };
        // No junk ever became a model; nothing planned without one.
        assert_eq!(
            (s.denoiser, s.discriminator, s.last_plan),
            (None, None, None)
        );
        sent += n;
        replies_seen += got.len();
    }
    eprintln!(
        "fuzz: {sent} mutated frames (seed {seed}), {replies_seen} replies, {:.1} s",
        t0.elapsed().as_secs_f64()
    );
}
