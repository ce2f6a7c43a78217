/* thread_sched.c: the calling thread's nice value, policy and time slice (see thread_sched.h).
 * sched_setattr has no wrapper before glibc 2.41, so it is called through syscall(2) with the
 * kernel's struct sched_attr, declared here in its first (48-byte) layout, which the kernel keeps
 * accepting (SCHED_ATTR_SIZE_VER0): linux/sched/types.h would clash with newer glibc's own. Its
 * sched_runtime is the slice request of a SCHED_OTHER / SCHED_BATCH thread (Linux 6.12,
 * kernel/sched/syscalls.c __setscheduler_params). */
#define _GNU_SOURCE
#include "base/thread_sched.h"

#include <errno.h>
#include <sched.h>
#include <stdint.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

/* the kernel's struct sched_attr, SCHED_ATTR_SIZE_VER0 */
struct sched_attr_v0 {
    uint32_t size, sched_policy;
    uint64_t sched_flags;
    int32_t sched_nice;
    uint32_t sched_priority;
    uint64_t sched_runtime, sched_deadline, sched_period;
};

int thread_sched_set(int nice, int slice_us, int policy)
{
#if defined(__linux__) && defined(SYS_sched_setattr)
    struct sched_attr_v0 a;
    memset(&a, 0, sizeof a);
    a.size = sizeof a;
    a.sched_policy = policy == THREAD_SCHED_IDLE    ? SCHED_IDLE
                     : policy == THREAD_SCHED_BATCH ? SCHED_BATCH
                                                    : SCHED_OTHER;
    a.sched_nice = nice;
    a.sched_runtime = slice_us > 0 ? (uint64_t)slice_us * 1000u : 0;
    if (syscall(SYS_sched_setattr, 0, &a, 0) == 0) return 0;
    int e = errno;
    if (!slice_us) return -e;
    a.sched_runtime = 0; /* an older kernel: nice and the policy without the slice */
    if (syscall(SYS_sched_setattr, 0, &a, 0) != 0) return -errno;
    return -e;
#else
    (void)slice_us;
    (void)policy;
    return setpriority(PRIO_PROCESS, 0, nice) ? -errno : 0;
#endif
}
