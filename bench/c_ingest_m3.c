/* MAVLink's own C parser on the emulated Cortex-M3 (MPS2-AN385), bare metal: the
 * reference for bench_mcu_ingest.py, which builds this -O2 against headers pymavlink's
 * mavgen generates, links it with c_ingest_m3.ld and runs it under qemu-system-arm
 * -icount shift=0 -semihosting, the stream put in RAM by QEMU's loader.
 *
 * The stream (STREAM_LEN bytes, the length a word QEMU's loader writes too) goes byte by
 * byte through mavlink_parse_char, PASSES times, timed by CMSDK APB timer 0 at 25 MHz:
 * under -icount shift=0 a guest instruction is one virtual ns, so a tick is 40
 * instructions. A loop of known length checks that. Printed (semihosting), one line:
 *   "frames ticks_best ticks_empty calibration_ticks calibration_instructions"
 * frames being those of the last pass (each pass must give the same), ticks_empty the
 * ticks of the timing itself around nothing.
 */
#include <stdint.h>

#include "common/mavlink.h"

#define STREAM ((const uint8_t *)0x00200000)
#define STREAM_LEN (*(volatile const uint32_t *)0x001FFFF0)
#define TIMER_CTRL (*(volatile uint32_t *)0x40000000)
#define TIMER_VALUE (*(volatile uint32_t *)0x40000004) /* counts down */
#define TIMER_RELOAD (*(volatile uint32_t *)0x40000008)
#define PASSES 3
#define CALIBRATION_LOOPS 1000000 /* of two instructions each */
#define SYS_WRITE0 0x04
#define SYS_EXIT 0x18
#define ADP_STOPPED_APPLICATION_EXIT 0x20026
#define ADP_STOPPED_RUNTIME_ERROR 0x20023
#define BARRIER() __asm__ volatile("" ::: "memory")

extern uint32_t _sbss, _ebss, _estack;

static mavlink_message_t msg;
static mavlink_status_t status;

static int semihost(int op, const void *arg)
{
    register int r0 __asm__("r0") = op;
    register const void *r1 __asm__("r1") = arg;
    __asm__ volatile("bkpt 0xAB" : "+r"(r0) : "r"(r1) : "memory");
    return r0;
}

static void __attribute__((noreturn)) stop(int reason)
{
    semihost(SYS_EXIT, (const void *)reason);
    for (;;) {
    }
}

static char *put_number(char *out, uint32_t v)
{
    char digits[10];
    int n = 0;
    do {
        digits[n++] = '0' + v % 10;
        v /= 10;
    } while (v);
    while (n)
        *out++ = digits[--n];
    *out++ = ' ';
    return out;
}

static uint32_t parse_pass(uint32_t *frames)
{
    uint32_t len = STREAM_LEN, got = 0;
    uint32_t t0 = TIMER_VALUE;
    BARRIER();
    for (uint32_t i = 0; i < len; i++) {
        if (mavlink_parse_char(MAVLINK_COMM_0, STREAM[i], &msg, &status) == MAVLINK_FRAMING_OK)
            got++;
    }
    BARRIER();
    uint32_t t1 = TIMER_VALUE;
    *frames = got;
    return t0 - t1;
}

static uint32_t empty_pass(void)
{
    uint32_t t0 = TIMER_VALUE;
    BARRIER();
    uint32_t t1 = TIMER_VALUE;
    return t0 - t1;
}

static uint32_t calibration(void)
{
    uint32_t n = CALIBRATION_LOOPS;
    uint32_t t0 = TIMER_VALUE;
    __asm__ volatile("1: subs %0, #1\n\tbne 1b" : "+r"(n) : : "cc");
    return t0 - TIMER_VALUE;
}

int main(void)
{
    TIMER_RELOAD = 0xFFFFFFFF;
    TIMER_VALUE = 0xFFFFFFFF;
    TIMER_CTRL = 1; /* enable */
    uint32_t frames = 0, first = 0, best = 0xFFFFFFFF;
    for (int pass = 0; pass < PASSES; pass++) {
        uint32_t ticks = parse_pass(&frames);
        if (pass == 0)
            first = frames;
        else if (frames != first)
            stop(ADP_STOPPED_RUNTIME_ERROR);
        if (ticks < best)
            best = ticks;
    }
    char line[64], *p = line;
    p = put_number(p, frames);
    p = put_number(p, best);
    p = put_number(p, empty_pass());
    p = put_number(p, calibration());
    p = put_number(p, 2 * CALIBRATION_LOOPS);
    p[-1] = '\n';
    *p = 0;
    semihost(SYS_WRITE0, line);
    return 0;
}

void Reset_Handler(void)
{
    for (uint32_t *p = &_sbss; p < &_ebss; p++)
        *p = 0;
    main();
    stop(ADP_STOPPED_APPLICATION_EXIT);
}

static void Fault_Handler(void)
{
    stop(ADP_STOPPED_RUNTIME_ERROR);
}

/* Initial stack pointer, reset, NMI, HardFault, MemManage, BusFault, UsageFault. */
__attribute__((section(".isr_vector"), used)) static const void *const vectors[] = {
    &_estack, Reset_Handler, Fault_Handler, Fault_Handler, Fault_Handler, Fault_Handler,
    Fault_Handler,
};
