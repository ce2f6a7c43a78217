/* thread_sched.h: the calling thread's place in the Linux scheduler: its nice value (per thread on
 * Linux) and its time slice (the EEVDF scheduler's custom slice, Linux 6.12 and later), so that
 * the latency-bound threads (HTTP) preempt the throughput-bound ones (fits, other processes) on
 * wakeup and the latter yield the CPU. libc and the raw system calls only. */
#ifndef IPSD_BASE_THREAD_SCHED_H
#define IPSD_BASE_THREAD_SCHED_H

/* The policies (thread_sched_set's policy). */
enum thread_sched_policy {
    THREAD_SCHED_NORMAL = 0, /* SCHED_OTHER: weighted by the nice value */
    THREAD_SCHED_BATCH = 1,  /* SCHED_BATCH: the same weight, never preempts on wakeup */
    THREAD_SCHED_IDLE = 2    /* SCHED_IDLE: runs when nothing else wants the CPU (weight 3) */
};

/* Gives the calling thread the nice value nice (-20..19) and, when slice_us > 0, a time slice of
 * slice_us microseconds (the kernel clamps it to 100..100000 us) under the policy (a
 * THREAD_SCHED_*). Entering any needs no privilege; leaving SCHED_IDLE again does (CAP_SYS_NICE,
 * or an RLIMIT_NICE that allows the thread's nice value: kernel/sched/syscalls.c), so a thread
 * that may need to come back should not enter it. Returns 0, or -errno:
 * EINVAL/ENOSYS from a kernel without custom slices (before 6.12 a slice is refused; nice and
 * the policy are still set then), EPERM for a nice below the current one without the
 * privilege. */
int thread_sched_set(int nice, int slice_us, int policy);

#endif
