/* memcpy for the app. picolibc's, built for size, copies one byte per six instructions and a
 * taken branch (~9 cycles per byte on VexRiscv); the app's copies are word-aligned structures
 * (a geometry job, its first echoes, a sensor's placement), which this copies by words. The
 * loops must stay loops: GCC would turn them back into a call to memcpy. */
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "app.h"

typedef uint32_t __attribute__((may_alias)) word_t;

APP_HOT __attribute__((optimize("no-tree-loop-distribute-patterns")))
void *memcpy(void *restrict dst, const void *restrict src, size_t n)
{
    unsigned char *d = dst;
    const unsigned char *s = src;
    if (((uintptr_t)d & 3u) == 0u && ((uintptr_t)s & 3u) == 0u)
        for (; n >= 4u; n -= 4u, d += 4, s += 4)
            *(word_t *)(void *)d = *(const word_t *)(const void *)s;
    for (; n > 0u; n--)
        *d++ = *s++;
    return dst;
}
