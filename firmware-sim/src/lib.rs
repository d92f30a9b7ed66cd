//! `dips-firmware-sim`: the kernel as the hand's controller runs it.
