/* core/base/sha256.h: SHA-256 (FIPS 180-4), for the configuration hash that ties an MVM control
 * matrix to the system it was built for (SPEC §9). None of the project's dependencies offers a hash. */
#ifndef WT_SHA256_H
#define WT_SHA256_H

#include <stddef.h>
#include <stdint.h>

/* hex: 65 bytes (64 lowercase hex digits and a terminating NUL). */
void wt_sha256_hex(const void *data, size_t len, char hex[65]);
void wt_sha256(const void *data, size_t len, uint8_t digest[32]);

/* The SHA-256 (hex) of a regular file's bytes, e.g. the LGS sodium profile that the matrix identity must
 * follow (docs/design.md "Diffractive sensing"). Opened without waiting (O_NONBLOCK: a FIFO or device is
 * refused, never read), at most WT_SHA256_FILE_MAX bytes. Returns 0, or -1 with errno set (ENOENT, EACCES,
 * EISDIR/EINVAL for not a regular file, EFBIG above the cap, ENOMEM). Allocates the file's size and frees it. */
#define WT_SHA256_FILE_MAX ((size_t)64 << 20)
int wt_sha256_file(const char *path, char hex[65]);

#endif
