//! A `#![no_std]` `#![no_main]` firmware image for `thumbv7em-none-eabihf` (Cortex-M4F/M7):
//! the firmware core served over a memory-mapped byte port. It proves that the whole
//! firmware — wire, upload checks, the planner and the interpreter — links for the
//! controller's target without std, and `size` reports what it occupies. The port addresses
//! stand for a UART's data registers; a real board crate would supply its own.
#![no_std]
#![no_main]
#![allow(unsafe_code)] // the entry point, the port registers and the static buffers

use dips_firmware_core::Firmware;
use dips_firmware_core::planning::PlanMemory;
use dips_kernel::budget::Clock;
use dips_kernel::search::PaperPlanner;
use dips_wire::{
    Feed, Frame, FrameAccumulator, FromKernel, MAX_ENCODED_FRAME_LEN, NO_REQUEST_ID, ToKernel,
    decode_frame, encode_frame,
};

/// Receive and transmit data registers of the byte port.
const PORT_RX: *const u32 = 0x4000_4400 as *const u32;
const PORT_TX: *mut u32 = 0x4000_4404 as *mut u32;
/// A free-running microsecond timer.
const TIMER_US: *const u32 = 0xE000_1004 as *const u32;

/// Model buffers (denoiser, discriminator, staging) and the planning work area, sized for the
/// shipped models at one segment per engine call (`docs/wire.md`, controller budget).
const MODEL_BYTES: usize = 2_400_000;
const WORK_FLOATS: usize = 970_000;

static mut DENOISER: [u8; MODEL_BYTES] = [0; MODEL_BYTES];
static mut DISCRIMINATOR: [u8; MODEL_BYTES] = [0; MODEL_BYTES];
static mut STAGING: [u8; MODEL_BYTES] = [0; MODEL_BYTES];
static mut WORK: [f32; WORK_FLOATS] = [0.0; WORK_FLOATS];
static mut PLANNER: PaperPlanner = PaperPlanner::new();

struct Timer {
    high: u64,
    last: u32,
}

impl Clock for Timer {
    fn now_us(&mut self) -> u64 {
        // SAFETY: a read of the timer register.
        let now = unsafe { core::ptr::read_volatile(TIMER_US) };
        if now < self.last {
            self.high += 1 << 32;
        }
        self.last = now;
        self.high | u64::from(now)
    }
}

fn read_byte() -> u8 {
    // SAFETY: a read of the port's receive register.
    unsafe { core::ptr::read_volatile(PORT_RX) as u8 }
}

fn write_bytes(bytes: &[u8]) {
    for &b in bytes {
        // SAFETY: a write to the port's transmit register.
        unsafe { core::ptr::write_volatile(PORT_TX, u32::from(b)) };
    }
}

#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    loop {}
}

#[unsafe(no_mangle)]
pub extern "C" fn Reset() -> ! {
    // SAFETY: the only references ever made to the static buffers, made once at reset.
    let (den, disc, stage, work, planner) = unsafe {
        (
            &mut *core::ptr::addr_of_mut!(DENOISER),
            &mut *core::ptr::addr_of_mut!(DISCRIMINATOR),
            &mut *core::ptr::addr_of_mut!(STAGING),
            &mut *core::ptr::addr_of_mut!(WORK),
            &mut *core::ptr::addr_of_mut!(PLANNER),
        )
    };
    let mut fw = Firmware::with_planning(den, disc, stage, PlanMemory { planner, work });
    let mut clock = Timer { high: 0, last: 0 };
    let mut acc = FrameAccumulator::<MAX_ENCODED_FRAME_LEN>::new();
    let mut tx = [0u8; MAX_ENCODED_FRAME_LEN];
    loop {
        let byte = [read_byte()];
        let reply = match acc.feed(&byte) {
            Feed::Consumed => continue,
            Feed::Frame { payload, .. } => match decode_frame::<ToKernel>(payload) {
                Ok(frame) => {
                    fw.count_request();
                    Frame {
                        request_id: frame.request_id,
                        body: fw.handle(frame.request_id, &frame.body, &mut clock),
                    }
                }
                Err(e) => {
                    fw.count_bad_frame();
                    Frame {
                        request_id: e.request_id.unwrap_or(NO_REQUEST_ID),
                        body: FromKernel::Error(e.error),
                    }
                }
            },
            Feed::Error { error, .. } => {
                fw.count_bad_frame();
                Frame {
                    request_id: NO_REQUEST_ID,
                    body: FromKernel::Error(error),
                }
            }
        };
        if let Ok(bytes) = encode_frame(&reply, &mut tx) {
            write_bytes(bytes);
            fw.count_reply();
        }
    }
}
