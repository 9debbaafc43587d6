/* core/model/tomography_noise.c: the tomography's noise weights after a sensor's noise model changed (a
 * diffractive LGS whose reference was rebuilt in the loop: SPEC §12 "The sodium layer changes too"). */
#include "tomography_private.h"

int wt_tomography_refresh_noise(wt_tomography *t)
{
    const int st = wt_tomography__noise(t);
    if (st < 0) return st;
    t->fresh = 1; /* the next solve applies M: the previous residual belongs to the old operator */
    return WT_OK;
}
