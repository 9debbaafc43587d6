/* wavetomo/wavetomo.h: the umbrella header of the wavetomo C library (docs/c-api.md).
 *
 *   #include <wavetomo/wavetomo.h>          cc prog.c $(pkg-config --cflags --libs wavetomo)
 *
 * The headers under include/wavetomo/ are the library's public, stable interface: the version
 * (version.h), status codes and the context (context.h), and the per-frame reconstructor (rtc.h).
 * Everything else in the source tree is internal and may change between versions.
 */
#ifndef WAVETOMO_WAVETOMO_H
#define WAVETOMO_WAVETOMO_H

#include "version.h"
#include "context.h"
#include "rtc.h"

#endif
