use std::process::ExitCode;

fn main() -> ExitCode {
    keep_freed_memory();
    propsim::command_line()
}

/// Lets glibc's allocator keep freed memory for reuse instead of returning it to the system:
/// a BVH build allocates and frees a few hundred MB in stages, and fresh pages cost a page
/// fault each on first touch (`bench trace`: 162 k faults and 0.40 s build, 78 k and 0.29 s
/// with this).
fn keep_freed_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallopt only sets allocator parameters; called before any thread starts.
    unsafe {
        // Blocks of any size from the heap, not from mmap (which unmaps them on free)...
        libc::mallopt(libc::M_MMAP_THRESHOLD, 1 << 30);
        // ... and the heap's free top kept rather than trimmed.
        libc::mallopt(libc::M_TRIM_THRESHOLD, i32::MAX);
    }
}
