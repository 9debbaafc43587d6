/* core/model/stack.c: Σ over sensors of Γ_m P_m and one sensor's transpose (see stack.h). */
#include "stack.h"

#include <string.h>

void wt_sensor_stack_set_sensor(const wt_sensor_stack *st, int m, double alpha, const double *x, double *y,
                                double *phase)
{
    const wt_sensor *s = &st->sys->sensors[m];
    memset(phase, 0, (size_t)wt_grid_size(&st->sys->sense_grid) * sizeof *phase);
    for (int l = 0; l < st->nin; l++) wt_projection_apply(st->proj[m * st->nin + l], 1.0, x + st->in_offset[l], phase);
    memset(y + s->offset, 0, (size_t)s->nslopes * sizeof *y);
    wt_shack_hartmann_apply(s->sh, alpha, phase, y + s->offset);
}

static void stack_apply(const wt_sensor_stack *st, double alpha, const double *x, double *y, double *phase,
                        int nthreads, int zero)
{
    const wt_system *sys = st->sys;
    const int64_t ncg = wt_grid_size(&sys->sense_grid);
#pragma omp parallel for schedule(dynamic, 1) num_threads(nthreads > 0 ? nthreads : 1)
    for (int m = 0; m < sys->nsensors; m++) {
        double *ph = phase + (size_t)m * ncg;
        if (zero) {
            wt_sensor_stack_set_sensor(st, m, alpha, x, y, ph);
            continue;
        }
        memset(ph, 0, (size_t)ncg * sizeof *ph);
        for (int l = 0; l < st->nin; l++) wt_projection_apply(st->proj[m * st->nin + l], 1.0, x + st->in_offset[l], ph);
        wt_shack_hartmann_apply(sys->sensors[m].sh, alpha, ph, y + sys->sensors[m].offset);
    }
}

void wt_sensor_stack_apply(const wt_sensor_stack *st, double alpha, const double *x, double *y, double *phase,
                           int nthreads)
{
    stack_apply(st, alpha, x, y, phase, nthreads, 0);
}

void wt_sensor_stack_set(const wt_sensor_stack *st, double alpha, const double *x, double *y, double *phase,
                         int nthreads)
{
    stack_apply(st, alpha, x, y, phase, nthreads, 1);
}

void wt_sensor_stack_phase_t(const wt_sensor_stack *st, int m, double alpha, const double *y_m, double *phase)
{
    const wt_system *sys = st->sys;
    memset(phase, 0, (size_t)wt_grid_size(&sys->sense_grid) * sizeof *phase);
    wt_shack_hartmann_apply_t(sys->sensors[m].sh, alpha, y_m, phase);
}

void wt_sensor_stack_apply_t_sensor(const wt_sensor_stack *st, int m, double alpha, const double *y_m, double *x,
                                    double *phase)
{
    wt_sensor_stack_phase_t(st, m, alpha, y_m, phase);
    for (int l = 0; l < st->nin; l++) wt_projection_apply_t(st->proj[m * st->nin + l], 1.0, phase, x + st->in_offset[l]);
}

/* Single precision (recon.<variant>.operator_precision = "fp32"): the same steps on float layers, phases, slopes */

void wt_sensor_stack_set_sensor_f32(const wt_sensor_stack *st, int m, float alpha, const float *x, float *y,
                                    float *phase)
{
    const wt_sensor *s = &st->sys->sensors[m];
    memset(phase, 0, (size_t)wt_grid_size(&st->sys->sense_grid) * sizeof *phase);
    for (int l = 0; l < st->nin; l++)
        wt_projection_apply_f32(st->proj[m * st->nin + l], 1.0f, x + st->in_offset[l], phase);
    memset(y + s->offset, 0, (size_t)s->nslopes * sizeof *y);
    wt_shack_hartmann_apply_f32(s->sh, alpha, phase, y + s->offset);
}

void wt_sensor_stack_phase_t_f32(const wt_sensor_stack *st, int m, float alpha, const float *y_m, float *phase)
{
    const wt_system *sys = st->sys;
    memset(phase, 0, (size_t)wt_grid_size(&sys->sense_grid) * sizeof *phase);
    wt_shack_hartmann_apply_t_f32(sys->sensors[m].sh, alpha, y_m, phase);
}

void wt_sensor_stack_apply_t_sensor_f32(const wt_sensor_stack *st, int m, float alpha, const float *y_m, float *x,
                                        float *phase)
{
    wt_sensor_stack_phase_t_f32(st, m, alpha, y_m, phase);
    for (int l = 0; l < st->nin; l++)
        wt_projection_apply_t_f32(st->proj[m * st->nin + l], 1.0f, phase, x + st->in_offset[l]);
}
