/* heap_huge.c: the malloc heap on transparent huge pages (heap_huge.h).
 *
 * glibc's main arena grows the program break (sbrk) and writes a chunk header at the start of
 * each new region. A 2 MiB block of which any 4 KiB page is already mapped can no longer get a
 * huge page on a fault, so the break is first moved to one page below a 2 MiB boundary: the
 * header of the region glibc then adds lands in that page, and everything from the boundary up
 * is still unmapped when the advice is given. Freeing the block makes it the arena's top chunk,
 * which later allocations are cut from. */
#include "base/heap_huge.h"

#include <stdint.h>
#include <stdlib.h>
#include <sys/mman.h>
#include <unistd.h>

#define HUGE_PAGE ((uintptr_t)2 << 20) /* x86-64's PMD size */
#define SMALL_PAGE ((uintptr_t)4096)

size_t heap_huge_pages(size_t bytes)
{
    void *brk0 = sbrk(0);
    if (brk0 == (void *)-1 || bytes < HUGE_PAGE) return 0;
    uintptr_t s0 = (uintptr_t)brk0;
    uintptr_t a = (s0 + SMALL_PAGE + HUGE_PAGE - 1) & ~(HUGE_PAGE - 1); /* first boundary */
    if (sbrk((intptr_t)(a - SMALL_PAGE - s0)) == (void *)-1) return 0;
    void *volatile block = malloc(bytes); /* volatile: the pair must not be optimised away */
    free(block);
    uintptr_t b = (uintptr_t)sbrk(0) & ~(HUGE_PAGE - 1);
    if (!block || b <= a) return 0; /* the allocator did not take it from the break */
    return madvise((void *)a, b - a, MADV_HUGEPAGE) == 0 ? b - a : 0;
}
