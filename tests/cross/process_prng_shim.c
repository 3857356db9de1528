/* Test-only stand-in for Windows 10's bcryptprimitives.dll, which Wine 8.0 lacks: Rust's
 * std (1.78+) imports ProcessPrng from it. Placed beside the harness under Wine only; the
 * shipped DLL is unchanged and finds the real one on Windows. */
#include <windows.h>
#include <bcrypt.h>

__declspec(dllexport) BOOL WINAPI ProcessPrng(PBYTE data, SIZE_T length) {
    return BCRYPT_SUCCESS(BCryptGenRandom(NULL, data, (ULONG)length,
                                          BCRYPT_USE_SYSTEM_PREFERRED_RNG));
}
