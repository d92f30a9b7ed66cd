//! `dips-onnx`: the DIPS model contract v1, tract loading and lowering to the kernel blob.
