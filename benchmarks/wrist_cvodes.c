/* The fig 4.15 wrist (wrist_equations.h) integrated by SUNDIALS CVODES: variable-order
 * BDF with Newton iterations on a dense linear solver and CVODES's own
 * difference-quotient Jacobian, the implicit baseline of benchmarks/run.py. Built
 * there against Debian's libsundials-dev when it is installed.
 */
#include <cvodes/cvodes.h>
#include <nvector/nvector_serial.h>
#include <sunlinsol/sunlinsol_dense.h>
#include <sunmatrix/sunmatrix_dense.h>

#include "wrist_equations.h"

static int rhs(sunrealtype t, N_Vector y, N_Vector dy, void *data) {
    derivatives(t, N_VGetArrayPointer(y), (const double *)data, N_VGetArrayPointer(dy));
    return 0;
}

/* From rest, the state at each of the n_out times t_out into out (rows of 4);
 * returns the number of right-hand side evaluations (with the Jacobian's), or -1. */
long cvodes_bdf(const double *c, double rtol, double atol, const double *t_out, long n_out,
                double *out) {
    SUNContext ctx;
    N_Vector y;
    SUNMatrix A;
    SUNLinearSolver solver;
    void *mem;
    long i, k, evals = -1, jac_evals = 0;
    sunrealtype t = 0.0;
    if (SUNContext_Create(NULL, &ctx) != 0)
        return -1;
    y = N_VNew_Serial(4, ctx);
    for (k = 0; k < 4; k++)
        NV_Ith_S(y, k) = 0.0;
    mem = CVodeCreate(CV_BDF, ctx);
    A = SUNDenseMatrix(4, 4, ctx);
    solver = SUNLinSol_Dense(y, A, ctx);
    if (mem && A && solver && CVodeInit(mem, rhs, 0.0, y) == CV_SUCCESS
        && CVodeSStolerances(mem, rtol, atol) == CV_SUCCESS
        && CVodeSetUserData(mem, (void *)c) == CV_SUCCESS
        && CVodeSetMaxNumSteps(mem, 10000000) == CV_SUCCESS
        && CVodeSetLinearSolver(mem, solver, A) == CV_SUCCESS) {
        for (i = 0; i < n_out; i++) {
            if (t_out[i] > t && CVode(mem, t_out[i], y, &t, CV_NORMAL) < 0)
                break;
            for (k = 0; k < 4; k++)
                out[4 * i + k] = NV_Ith_S(y, k);
        }
        if (i == n_out && CVodeGetNumRhsEvals(mem, &evals) == CV_SUCCESS
            && CVodeGetNumLinRhsEvals(mem, &jac_evals) == CV_SUCCESS)
            evals += jac_evals;
        else
            evals = -1;
    }
    CVodeFree(&mem);
    SUNLinSolFree(solver);
    SUNMatDestroy(A);
    N_VDestroy(y);
    SUNContext_Free(&ctx);
    return evals;
}
