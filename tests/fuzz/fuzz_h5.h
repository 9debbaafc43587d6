/* tests/fuzz/fuzz_h5.h: the HDF5 targets' own leak check.
 *
 * LeakSanitizer cannot see an HDF5 identifier the reader forgets to close (HDF5's id tables keep it
 * reachable), and it reports blocks that libhdf5 1.10.8 itself loses while it refuses some corrupt
 * object headers (inside H5O_protect; suppressed in tests/fuzz/lsan.supp). So each input must leave as
 * many open files, datasets, groups, attributes, datatypes, dataspaces and property lists as before. */
#ifndef WT_FUZZ_H5_H
#define WT_FUZZ_H5_H

#include <hdf5.h>
#include <stdio.h>
#include <stdlib.h>

static inline long fuzz_h5_open_ids(void)
{
    static const H5I_type_t kinds[] = {H5I_FILE, H5I_GROUP, H5I_DATATYPE, H5I_DATASPACE, H5I_DATASET,
                                       H5I_ATTR, H5I_GENPROP_LST};
    long total = 0;
    for (size_t i = 0; i < sizeof kinds / sizeof *kinds; i++) {
        hsize_t n = 0;
        if (H5Inmembers(kinds[i], &n) >= 0) total += (long)n;
    }
    return total;
}

/* Abort (a finding) when the input left HDF5 identifiers open. */
static inline void fuzz_h5_check_ids(long before)
{
    long after = fuzz_h5_open_ids();
    if (after != before) {
        fprintf(stderr, "fuzz: %ld HDF5 identifier(s) left open by this input\n", after - before);
        abort();
    }
}

#endif
