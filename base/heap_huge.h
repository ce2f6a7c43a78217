/* heap_huge.h: backs a short-lived numeric process's malloc heap with transparent huge pages.
 *
 * Every first touch of a 4 KiB page is a page fault, and on a virtual machine a fault is dear:
 * 14 us each on the 2-core Firecracker VM ipsd's figures come from (bench/README.md), where the
 * 41 x 41 sweep of `ips fit` touched 26 MB in 6,666 faults, a third of its CPU time, and the
 * 81-point reference fit a third of its 10 ms in 340. A 2 MiB huge page costs one fault.
 * glibc can ask for them itself (the tunable glibc.malloc.hugetlb=1), but a tunable is read from
 * the environment at start-up, so a program cannot set it for itself; this does what the tunable
 * does, once, at the top of main. libc and the raw system calls only. */
#ifndef IPSD_BASE_HEAP_HUGE_H
#define IPSD_BASE_HEAP_HUGE_H

#include <stddef.h>

/* Grows the malloc heap (the main arena, from the program break) by about bytes, keeps it (the
 * caller raises M_TRIM_THRESHOLD above bytes, and M_MMAP_THRESHOLD so that big blocks come from
 * the heap at all) and advises the kernel to back it with huge pages (MADV_HUGEPAGE: honoured
 * when /sys/kernel/mm/transparent_hugepage/enabled is always or madvise). Only address space
 * is taken: memory is used as it is touched, 2 MiB at a time. Call before the program's work,
 * on one thread, in a process that exits rather than trims (ipsd trims: not there). Returns the
 * bytes advised, 0 when nothing was (no program break to grow, an allocator that does not use
 * it, e.g. AddressSanitizer's, or a kernel without transparent huge pages); the program runs the
 * same either way. */
size_t heap_huge_pages(size_t bytes);

#endif
