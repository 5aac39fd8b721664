//! Building and running the QEMU firmware (filled in with the QEMU tests).
