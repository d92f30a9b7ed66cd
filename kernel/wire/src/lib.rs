//! `dips-wire`: postcard messages and COBS framing between the DIPS host and kernel.
#![no_std]
#![forbid(unsafe_code)]

#[cfg(test)]
extern crate std;
