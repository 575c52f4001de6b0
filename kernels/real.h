// The kernels' number type: float32 by default, float64 with -DREAL_DOUBLE=1 on a device with
// cl_khr_fp64. Kernels use `real`/`real2`/`real4` and write literals as R(1.5), so both builds
// see the same code. FP_CONTRACT is off so a*b + c is never fused and the float64 build rounds
// exactly like the NumPy references, which evaluate the same expressions in the same order.

#pragma OPENCL FP_CONTRACT OFF

#ifdef REAL_DOUBLE
#pragma OPENCL EXTENSION cl_khr_fp64 : enable
typedef double real;
typedef double2 real2;
typedef double4 real4;
#define R(x) ((double)(x))
#else
typedef float real;
typedef float2 real2;
typedef float4 real4;
#define R(x) ((float)(x))
#endif

#define M_PI_R R(3.14159265358979323846)
