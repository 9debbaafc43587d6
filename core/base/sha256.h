/* core/base/sha256.h: SHA-256 (FIPS 180-4), for the configuration hash that ties an MVM control
 * matrix to the system it was built for (SPEC §9). None of the project's dependencies offers a hash. */
#ifndef WT_SHA256_H
#define WT_SHA256_H

#include <stddef.h>
#include <stdint.h>

/* hex: 65 bytes (64 lowercase hex digits and a terminating NUL). */
void wt_sha256_hex(const void *data, size_t len, char hex[65]);
void wt_sha256(const void *data, size_t len, uint8_t digest[32]);

#endif
