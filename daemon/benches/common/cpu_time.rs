//! A process's CPU time for the benchmarks, from the scheduler's own per-thread accounting.

#![allow(dead_code)] // each bench uses a different part

/// On-CPU time of a task, ns: the first field of its `schedstat` (the scheduler's own
/// accounting, exact). Not `stat`'s utime + stime: those are charged a whole 10 ms clock tick to
/// whichever thread the tick finds running, which undercounts threads that run in short bursts
/// between ticks (rustdds's event loop read 1.2 % by ticks and 3.7 % by schedstat in one run).
pub fn cpu_ns_of(task_dir: &std::path::Path) -> u64 {
    std::fs::read_to_string(task_dir.join("schedstat"))
        .ok()
        .and_then(|s| s.split_whitespace().next()?.parse().ok())
        .unwrap_or(0)
}

/// On-CPU ns of the threads of `pid` whose name passes `keep` (summed over the threads alive in
/// `/proc/<pid>/task`).
pub fn thread_cpu_ns(pid: u32, keep: impl Fn(&str) -> bool) -> u64 {
    let Ok(tasks) = std::fs::read_dir(format!("/proc/{pid}/task")) else {
        return 0;
    };
    tasks
        .filter_map(Result::ok)
        .filter(|t| {
            keep(
                std::fs::read_to_string(t.path().join("comm"))
                    .unwrap_or_default()
                    .trim(),
            )
        })
        .map(|t| cpu_ns_of(&t.path()))
        .sum()
}

/// The whole process's threads.
pub fn cpu_ns(pid: u32) -> u64 {
    thread_cpu_ns(pid, |_| true)
}
