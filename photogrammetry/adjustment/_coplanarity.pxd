# Inline C of the coplanarity condition (private to photogrammetry.adjustment; shared by
# _pair_kernels.pyx and _msac_kernels.pyx): one angle triplet's rotation and axes, one tie
# point's condition terms, the tangent basis of a base direction, and the small dense
# algebra the kernels need.
#
# Matrices are C arrays row by row (M[3 * i + j]; E (3, 2) as E[2 * i + j]).  The dense
# algebra calls the BLAS and LAPACK of scipy (scipy.linalg.cython_blas / cython_lapack):
# the same routines, with the same arguments and workspace queries, that numba's
# np.linalg.eigh / eigvalsh / solve / inv and '@' called in the kernels these replaced,
# so the results are theirs bit for bit.  Every helper returns 0 on success or one of the
# LINALG_* codes below; the callers raise numpy.linalg.LinAlgError (as numba did).
from libc.math cimport cos, fabs, isfinite, sin, sqrt
from libc.stdlib cimport free, malloc
from scipy.linalg.cython_blas cimport ddot, dgemv
from scipy.linalg.cython_lapack cimport dgesv, dgetrf, dgetri, dsyevd

cdef enum:
    LINALG_OK = 0
    LINALG_NOT_FINITE = 1     # "Array must not contain infs or NaNs."
    LINALG_SINGULAR = 2       # "Matrix is singular to machine precision."
    LINALG_NO_CONVERGENCE = 3 # "Eigenvalues did not converge."
    LINALG_NO_MEMORY = 4


cdef inline void rotation(const double *a, const int *order, const double *sign,
                          double *R, double *M) noexcept nogil:
    """R = C_mc of one angle triplet and the model-frame axes M of its partial rotations
    (column k: the axis of angle k), as rotation_and_axes of _coplanarity_kernels."""
    cdef double T[9]
    cdef double c, s
    cdef int i, j, k, ax, i1, i2
    for i in range(3):
        for j in range(3):
            R[3 * i + j] = 1.0 if i == j else 0.0
    for k in range(3):
        ax = order[k]
        for i in range(3):
            M[3 * i + k] = sign[k] * R[3 * i + ax]
        c = cos(sign[k] * a[k])
        s = sin(sign[k] * a[k])
        i1 = (ax + 1) % 3
        i2 = (ax + 2) % 3
        for i in range(3):                       # R <- R @ elementary(ax, a[k])
            T[3 * i + ax] = R[3 * i + ax]
            T[3 * i + i1] = c * R[3 * i + i1] + s * R[3 * i + i2]
            T[3 * i + i2] = -s * R[3 * i + i1] + c * R[3 * i + i2]
        for i in range(9):
            R[i] = T[i]


cdef inline double terms(const double *r1, const double *u2, const double *R1,
                         const double *R2, const double *M2, const double *b,
                         const double *E, double s2, int k, double *Ji, double *N,
                         double *var) noexcept nogil:
    """One point: returns the misclosure g = b . (r1 x R2 u2); fills its variance var,
    the Jacobian row Ji (k,) (image 2's angles, then with k = 5 the two base-direction
    parameters of the tangent basis E) and N = r1 x r2 (3,)."""
    cdef double r2x = R2[0] * u2[0] + R2[1] * u2[1] + R2[2] * u2[2]
    cdef double r2y = R2[3] * u2[0] + R2[4] * u2[1] + R2[5] * u2[2]
    cdef double r2z = R2[6] * u2[0] + R2[7] * u2[1] + R2[8] * u2[2]
    cdef double g, t0, t1, t2, d1x, d1y, c0, c1, c2, d2x, d2y, a0, a1, a2
    cdef int j
    N[0] = r1[1] * r2z - r1[2] * r2y
    N[1] = r1[2] * r2x - r1[0] * r2z
    N[2] = r1[0] * r2y - r1[1] * r2x
    g = N[0] * b[0] + N[1] * b[1] + N[2] * b[2]
    t0 = r2y * b[2] - r2z * b[1]
    t1 = r2z * b[0] - r2x * b[2]
    t2 = r2x * b[1] - r2y * b[0]
    d1x = R1[0] * t0 + R1[3] * t1 + R1[6] * t2
    d1y = R1[1] * t0 + R1[4] * t1 + R1[7] * t2
    c0 = b[1] * r1[2] - b[2] * r1[1]                # b x r1
    c1 = b[2] * r1[0] - b[0] * r1[2]
    c2 = b[0] * r1[1] - b[1] * r1[0]
    d2x = R2[0] * c0 + R2[3] * c1 + R2[6] * c2
    d2y = R2[1] * c0 + R2[4] * c1 + R2[7] * c2
    var[0] = s2 * (d1x * d1x + d1y * d1y + d2x * d2x + d2y * d2y)
    a0 = r2y * c2 - r2z * c1                        # dg/dtheta2
    a1 = r2z * c0 - r2x * c2
    a2 = r2x * c1 - r2y * c0
    for j in range(3):
        Ji[j] = a0 * M2[j] + a1 * M2[3 + j] + a2 * M2[6 + j]
    if k == 5:
        for j in range(2):
            Ji[3 + j] = N[0] * E[j] + N[1] * E[2 + j] + N[2] * E[4 + j]
    return g


cdef inline double dot(int n, const double *x, const double *y) noexcept nogil:
    """x . y (BLAS ddot, as numba's '@' of two vectors)."""
    cdef int inc = 1
    return ddot(&n, <double *>x, &inc, <double *>y, &inc)


cdef inline void tangent(const double *b, double *E) noexcept nogil:
    """Two orthonormal vectors perpendicular to the unit vector b: the columns of E
    (3, 2), as tangent_basis of _coplanarity_kernels."""
    cdef double h[3]
    cdef double e1[3]
    cdef double nrm
    if fabs(b[0]) < 0.8:
        h[0], h[1], h[2] = 1.0, 0.0, 0.0
    else:
        h[0], h[1], h[2] = 0.0, 1.0, 0.0
    e1[0] = b[1] * h[2] - b[2] * h[1]
    e1[1] = b[2] * h[0] - b[0] * h[2]
    e1[2] = b[0] * h[1] - b[1] * h[0]
    nrm = sqrt(dot(3, e1, e1))
    e1[0] = e1[0] / nrm
    e1[1] = e1[1] / nrm
    e1[2] = e1[2] / nrm
    E[0], E[2], E[4] = e1[0], e1[1], e1[2]
    E[1] = b[1] * e1[2] - b[2] * e1[1]
    E[3] = b[2] * e1[0] - b[0] * e1[2]
    E[5] = b[0] * e1[1] - b[1] * e1[0]


cdef inline bint all_finite(int n, const double *x) noexcept nogil:
    cdef int i
    for i in range(n):
        if not isfinite(x[i]):
            return False
    return True


cdef inline int eigh(int n, const double *A, double *w, double *V) noexcept nogil:
    """Eigenvalues w (ascending) and, when V is not NULL, eigenvectors (V[n i + j] =
    vector j's component i) of the symmetric n x n matrix A: LAPACK dsyevd on the lower
    triangle of its column-major copy, after a workspace query (numba's eigh/eigvalsh)."""
    cdef char jobz = b'V' if V != NULL else b'N'
    cdef char uplo = b'L'
    cdef int lwork = -1, liwork = -1, info = 0, iw_query = 0, i, j
    cdef double w_query = 0.0
    cdef double *a
    cdef double *work
    cdef int *iwork
    if not all_finite(n * n, A):
        return LINALG_NOT_FINITE
    a = <double *>malloc(n * n * sizeof(double))
    if a == NULL:
        return LINALG_NO_MEMORY
    for i in range(n):
        for j in range(n):
            a[i + n * j] = A[n * i + j]
    dsyevd(&jobz, &uplo, &n, a, &n, w, &w_query, &lwork, &iw_query, &liwork, &info)
    lwork = <int>w_query
    liwork = iw_query
    work = <double *>malloc(lwork * sizeof(double))
    iwork = <int *>malloc(liwork * sizeof(int))
    if work == NULL or iwork == NULL:
        free(a)
        free(work)
        free(iwork)
        return LINALG_NO_MEMORY
    dsyevd(&jobz, &uplo, &n, a, &n, w, work, &lwork, iwork, &liwork, &info)
    free(work)
    free(iwork)
    if info == 0 and V != NULL:
        for i in range(n):
            for j in range(n):
                V[n * i + j] = a[i + n * j]
    free(a)
    return LINALG_OK if info == 0 else LINALG_NO_CONVERGENCE


cdef inline int solve(int n, const double *A, double *x) noexcept nogil:
    """x <- A^-1 x (LAPACK dgesv on A's column-major copy; numba's np.linalg.solve)."""
    cdef int nrhs = 1, info = 0, i, j
    cdef double *a
    cdef int *ipiv
    if not all_finite(n * n, A) or not all_finite(n, x):
        return LINALG_NOT_FINITE
    a = <double *>malloc(n * n * sizeof(double))
    ipiv = <int *>malloc(n * sizeof(int))
    if a == NULL or ipiv == NULL:
        free(a)
        free(ipiv)
        return LINALG_NO_MEMORY
    for i in range(n):
        for j in range(n):
            a[i + n * j] = A[n * i + j]
    dgesv(&n, &nrhs, a, &n, ipiv, x, &n, &info)
    free(a)
    free(ipiv)
    return LINALG_OK if info == 0 else LINALG_SINGULAR


cdef inline int inverse(int n, const double *A, double *Ainv) noexcept nogil:
    """Ainv = A^-1 (LAPACK dgetrf + dgetri with a workspace query, on A's column-major
    copy; numba's np.linalg.inv)."""
    cdef int lwork = -1, info = 0, i, j
    cdef double w_query = 0.0
    cdef double *a
    cdef double *work
    cdef int *ipiv
    if not all_finite(n * n, A):
        return LINALG_NOT_FINITE
    a = <double *>malloc(n * n * sizeof(double))
    ipiv = <int *>malloc(n * sizeof(int))
    if a == NULL or ipiv == NULL:
        free(a)
        free(ipiv)
        return LINALG_NO_MEMORY
    for i in range(n):
        for j in range(n):
            a[i + n * j] = A[n * i + j]
    dgetrf(&n, &n, a, &n, ipiv, &info)
    if info == 0:
        dgetri(&n, a, &n, ipiv, &w_query, &lwork, &info)
        lwork = <int>w_query
        work = <double *>malloc(lwork * sizeof(double))
        if work == NULL:
            free(a)
            free(ipiv)
            return LINALG_NO_MEMORY
        dgetri(&n, a, &n, ipiv, work, &lwork, &info)
        free(work)
    free(ipiv)
    if info == 0:
        for i in range(n):
            for j in range(n):
                Ainv[n * i + j] = a[i + n * j]
    free(a)
    return LINALG_OK if info == 0 else LINALG_SINGULAR


cdef inline void vecmat(int k, const double *x, const double *Q, double *y) noexcept nogil:
    """y = x @ Q for Q (k, k) row by row (BLAS dgemv, as numba's '@' of a vector and a
    C-ordered matrix: 'n' on the column-major view Q^T)."""
    cdef char trans = b'n'
    cdef int inc = 1
    cdef double one = 1.0, zero = 0.0
    dgemv(&trans, &k, &k, &one, <double *>Q, &k, <double *>x, &inc, &zero, y, &inc)


cdef inline void matvec_32(const double *E, const double *x, double *y) noexcept nogil:
    """y = E @ x for E (3, 2) row by row (BLAS dgemv, as numba's '@' of a C-ordered
    matrix and a vector: 't' on the column-major view E^T)."""
    cdef char trans = b't'
    cdef int m = 2, n = 3, inc = 1
    cdef double one = 1.0, zero = 0.0
    dgemv(&trans, &m, &n, &one, <double *>E, &m, <double *>x, &inc, &zero, y, &inc)


cdef inline double fmax2(double a, double b) noexcept nogil:
    """max(a, b) as Python (and numba) evaluate it: b if b > a else a."""
    return b if b > a else a
