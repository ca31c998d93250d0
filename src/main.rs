use std::process::ExitCode;

use clap::Parser;

fn main() -> ExitCode {
    keep_freed_memory();
    // `propsim ... | head` ends quietly, like other Unix tools, instead of panicking on EPIPE.
    sigpipe::reset();
    let cli = match propsim::cli::Cli::try_parse() {
        Ok(cli) => cli,
        // Usage errors on one line, like every other error; help and version print as usual.
        Err(e) if e.use_stderr() => {
            let text = e.render().to_string();
            let first = text.lines().find(|l| !l.trim().is_empty()).unwrap_or("error: invalid arguments");
            let first = first.trim();
            if first.starts_with("error:") {
                propsim::errln!("{first}");
            } else {
                propsim::errln!("error: {first}");
            }
            return ExitCode::from(2);
        }
        Err(e) => e.exit(),
    };
    // One process, or this process's place in an MPI job (`--features mpi`).
    let cluster = match propsim::dist::Cluster::from_environment() {
        Ok(c) => c,
        Err(e) => {
            propsim::errln!("error: {}", format!("{e:#}").replace('\n', " "));
            return ExitCode::FAILURE;
        }
    };
    let result = propsim::cli::run(cli, &cluster);
    // Standard output is checked too: a full disk behind `> file` is an error like any other;
    // a reader that went away (`| head`, with SIGPIPE ignored by the parent) ends us quietly.
    let result = match (result, propsim::io::stdout::finish()) {
        (Err(e), _) => Err(e),
        (Ok(()), Err(e)) if e.kind() == std::io::ErrorKind::BrokenPipe => return ExitCode::SUCCESS,
        (Ok(()), Err(e)) => Err(anyhow::anyhow!("cannot write standard output: {e}")),
        (Ok(()), Ok(())) => Ok(()),
    };
    match result {
        Ok(()) => {
            if cluster.is_root() && cluster.size() > 1 {
                let c = cluster.reduce_cost();
                propsim::errln!(
                    "mpi: {} processes; rank 0 waited {:.3} s for the others and reduced {:.2} MB in {:.3} s",
                    cluster.size(),
                    c.wait_s,
                    c.bytes as f64 / 1e6,
                    c.reduce_s
                );
            }
            ExitCode::SUCCESS
        }
        Err(e) => {
            // Every process of a job sees the same inputs and fails alike: rank 0 reports.
            if cluster.is_root() {
                propsim::errln!("error: {}", format!("{e:#}").replace('\n', " "));
            }
            ExitCode::FAILURE
        }
    }
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
