//! Keeping freed memory in the process: a training step or CPU frame allocates and frees
//! hundreds of tensors of a few hundred KiB. glibc's malloc maps each block over its mmap
//! threshold from the kernel and unmaps it when freed, and trims the heap top, so every
//! step page-faults its memory in again: 20-25% of a CPU training step's wall time
//! (`cargo run --release -p glassbake-bake --example train_step`, 2 cores).

/// Has the allocator serve tensors from its heap and keep what is freed for the next step.
/// Call it once, first thing in `main`, before any thread starts. A no-op off glibc.
pub fn keep_freed_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallopt only changes the allocator's tuning parameters; called before other
    // threads exist, as glibc asks.
    unsafe {
        // The largest threshold glibc accepts on 64-bit (HEAP_MAX_SIZE / 2): blocks up to it
        // come from the heap. Fixing it also stops glibc's own threshold from adapting.
        libc::mallopt(libc::M_MMAP_THRESHOLD, 32 << 20);
        // Return the heap's free top to the kernel only beyond 1 GiB, and grow it 64 MiB at a
        // time, so steady-state steps make no system calls for memory.
        libc::mallopt(libc::M_TRIM_THRESHOLD, 1 << 30);
        libc::mallopt(libc::M_TOP_PAD, 64 << 20);
    }
}
