/* runtime/rtc_internal.h: the drivers' side of the public per-frame API (include/wavetomo/rtc.h): an instance
 * opened on a system the caller has already built (`wavetomo run` checks the telemetry's shapes against
 * it before the reconstructor or the matrix is made or read). */
#ifndef WT_RTC_INTERNAL_H
#define WT_RTC_INTERNAL_H

#include "wavetomo/rtc.h"

#include "../core/model/system.h"

/* kind WT_RECON_PCG3, WT_RECON_CG9 or WT_RECON_NONE (matrix NULL; iterations ≥ 0 overrides the variant's
 * (P)CG count), or WT_RECON_MVM with the path of MATRIX.h5 (refused unless built for sys->cfg). only_ol:
 * every frame will carry WT_RTC_SLOPES_OL (pseudo-open-loop slopes), so Â is not built (a frame without
 * the flag, and wt_rtc_interaction, are then refused). sys (and its configuration) is not owned and must
 * outlive the instance and every share of it (wt_rtc_share). */
int wt_rtc_open_system(wt_context *ctx, const wt_system *sys, int kind, const char *matrix, int iterations,
                       int only_ol, wt_rtc **out);

#endif
