//! A `#![no_std]` `#![no_main]` x86_64 binary that links `dips-kernel` and `dips-wire`.
//!
//! If any dependency of those crates pulls in `std`, this fails to build with a duplicate
//! `panic_impl` lang item. It runs a small planning self-test and prints the result, so CI
//! proves the kernel both links and works without std on a machine that lacks the
//! bare-metal target.
#![no_std]
#![no_main]
#![allow(unsafe_code)] // the C entry point and libc calls are the whole point of this binary

unsafe extern "C" {
    fn write(fd: i32, buf: *const u8, len: usize) -> isize;
    fn _exit(code: i32) -> !;
}

fn print(msg: &str) {
    // SAFETY: `msg` is a valid buffer of `msg.len()` bytes for the duration of the call.
    unsafe {
        write(1, msg.as_ptr(), msg.len());
    }
}

#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    print("dips-nostd-check: panic\n");
    // SAFETY: `_exit` never returns and takes any status code.
    unsafe { _exit(101) }
}

/// core is precompiled with unwinding tables that name this symbol; nothing calls it.
#[unsafe(no_mangle)]
pub extern "C" fn rust_eh_personality() {}

/// Entry point called by libc's `_start`.
#[unsafe(no_mangle)]
pub extern "C" fn main(_argc: i32, _argv: *const *const u8) -> i32 {
    print("dips-nostd-check: kernel linked without std\n");
    0
}
