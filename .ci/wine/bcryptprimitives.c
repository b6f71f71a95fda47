/*
 * ProcessPrng for wine 8, test runs only.
 *
 * Rust's standard library for Windows asks bcryptprimitives.dll for ProcessPrng at start-up
 * (Windows 10 and later have it); wine 8's bcryptprimitives.dll lacks it, so every Rust
 * program stops before main. This DLL provides ProcessPrng over advapi32's RtlGenRandom
 * (exported as SystemFunction036), which wine has. .ci/cross-windows.sh builds it and puts it
 * beside the test programs; it is never shipped.
 */
#include <windows.h>

BOOLEAN WINAPI SystemFunction036(PVOID buffer, ULONG length);

BOOL WINAPI ProcessPrng(PBYTE data, SIZE_T length)
{
    while (length > 0) {
        ULONG chunk = length > 0x40000000 ? 0x40000000 : (ULONG)length;
        if (!SystemFunction036(data, chunk))
            return FALSE;
        data += chunk;
        length -= chunk;
    }
    return TRUE;
}
