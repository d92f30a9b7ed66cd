//! Compile-time encoded sizes for types postcard's `MaxSize` derive cannot handle.
//!
//! postcard implements `MaxSize` only for its own heapless 0.7 `Vec` (spec/deps.md G4), so the
//! structs that hold a `heapless::Vec` implement it by hand with these helpers.

pub use postcard::experimental::max_size::MaxSize;

/// Bytes of the LEB128 varint postcard writes for `n`.
pub const fn varint_len(n: u64) -> usize {
    let mut len = 1;
    let mut rest = n >> 7;
    while rest != 0 {
        len += 1;
        rest >>= 7;
    }
    len
}

/// Largest encoding of a `heapless::Vec<T, N>`: the length varint plus `N` elements.
pub const fn vec_max_size<T: MaxSize, const N: usize>() -> usize {
    varint_len(N as u64) + N * T::POSTCARD_MAX_SIZE
}

/// Largest COBS encoding of `len` bytes, without the `0x00` delimiter.
pub const fn cobs_max_encoded_len(len: usize) -> usize {
    len + len / 254 + 1
}

/// The larger of two sizes (`const` context).
pub const fn max(a: usize, b: usize) -> usize {
    if a > b { a } else { b }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn varint_lengths_match_postcard() {
        for n in [0u64, 1, 127, 128, 16_383, 16_384, u32::MAX as u64, u64::MAX] {
            let mut buf = [0u8; 16];
            let used = postcard::to_slice(&n, &mut buf).map(|s| s.len()).unwrap();
            assert_eq!(varint_len(n), used, "n = {n}");
        }
    }
}
