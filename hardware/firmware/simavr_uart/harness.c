/* simavr_uart: runs the light-board firmware in simavr with its serial port (UART0) behind a pty.
 *
 *   simavr_uart FIRMWARE.elf LINK [RXLOG]
 *
 * Loads FIRMWARE.elf on an ATmega328P at 16 MHz, runs it until its UART receiver is on, points the
 * symlink LINK at a new pty (as udev's /dev/serial/by-id/... names point at a tty) and prints
 * "ready <pty>" on stdout. It then runs no faster than real time until SIGTERM or SIGINT (or its
 * parent dies), and removes LINK. Every byte the AVR receives is appended to RXLOG.
 * Lines on stdin drive input pins, as a wire to ground would: "pin D 2 0" pulls PD2 low, "pin D 2 1"
 * lets it go high again; each is answered "ok pin D 2 0" on stdout once done.
 */
#define _GNU_SOURCE
#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

#include <avr_ioport.h>
#include <avr_uart.h>
#include <sim_avr.h>
#include <sim_elf.h>

#define FREQUENCY 16000000
#define SLICE_CYCLES (FREQUENCY / 1000) /* run 1 ms of AVR time between looks at the pty */

static volatile sig_atomic_t stopping = 0;
static int master = -1;      /* the pty's master side: the wire to the host */
static int rx_log = -1;
static int uart_full = 0;    /* the UART's input FIFO is full (XOFF): hold bytes back */

static void on_signal(int sig) { (void)sig; stopping = 1; }

static void die(const char *what) { perror(what); exit(1); }

/* A byte the firmware sends goes to the host; dropped if nobody has read the last 4 KiB. */
static void uart_output(avr_irq_t *irq, uint32_t value, void *param) {
    (void)irq; (void)param;
    uint8_t byte = value;
    if (write(master, &byte, 1) < 0 && errno != EAGAIN) perror("write pty");
}

static void uart_xoff(avr_irq_t *irq, uint32_t value, void *param) { (void)irq; (void)param; if (value) uart_full = 1; }
static void uart_xon(avr_irq_t *irq, uint32_t value, void *param) { (void)irq; (void)param; if (value) uart_full = 0; }

static double now_s(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return t.tv_sec + t.tv_nsec * 1e-9;
}

/* A pty in raw mode (no echo, no line editing, no CR/LF translation); its slave stays open here so
 * that the master does not read EIO while no host has the port open. */
static const char *open_pty(void) {
    master = posix_openpt(O_RDWR | O_NOCTTY);
    if (master < 0 || grantpt(master) < 0 || unlockpt(master) < 0) die("posix_openpt");
    const char *name = ptsname(master);
    int slave = open(name, O_RDWR | O_NOCTTY);
    if (slave < 0) die("open pty slave");
    struct termios tio;
    tcgetattr(slave, &tio);
    cfmakeraw(&tio);
    tcsetattr(slave, TCSANOW, &tio);
    fcntl(master, F_SETFL, O_NONBLOCK);
    return name;
}

static void point_link(const char *link, const char *target) {
    char tmp[4096];
    snprintf(tmp, sizeof tmp, "%s.tmp", link);
    unlink(tmp);
    if (symlink(target, tmp) < 0 || rename(tmp, link) < 0) die("symlink");
}

/* "pin D 2 0": drive pin 2 of port D low (0) or high (1). */
static void pin_command(avr_t *avr, const char *text) {
    char port;
    int pin, level;
    if (sscanf(text, "pin %c %d %d", &port, &pin, &level) != 3 || pin < 0 || pin > 7) {
        fprintf(stderr, "simavr_uart: unknown command %s\n", text);
        return;
    }
    avr_irq_t *irq = avr_io_getirq(avr, AVR_IOCTL_IOPORT_GETIRQ(port), pin);
    if (!irq) {
        fprintf(stderr, "simavr_uart: no port %c\n", port);
        return;
    }
    avr_raise_irq(irq, level != 0);
    printf("ok pin %c %d %d\n", port, pin, level != 0);
    fflush(stdout);
}

int main(int argc, char **argv) {
    if (argc < 3) {
        fprintf(stderr, "usage: %s FIRMWARE.elf LINK [RXLOG]\n", argv[0]);
        return 2;
    }
    elf_firmware_t firmware = {0};
    if (elf_read_firmware(argv[1], &firmware) != 0) die(argv[1]);
    avr_t *avr = avr_make_mcu_by_name("atmega328p");
    if (!avr) die("atmega328p");
    firmware.frequency = FREQUENCY;
    avr_init(avr);
    avr_load_firmware(avr, &firmware);
    avr->log = LOG_ERROR;  /* simavr's errors go to stderr */
    if (argc > 3 && (rx_log = open(argv[3], O_WRONLY | O_CREAT | O_APPEND, 0644)) < 0) die(argv[3]);

    uint32_t flags = 0;  /* no copy of the firmware's output on our stdout */
    avr_ioctl(avr, AVR_IOCTL_UART_GET_FLAGS('0'), &flags);
    flags &= ~AVR_UART_FLAG_STDIO;
    avr_ioctl(avr, AVR_IOCTL_UART_SET_FLAGS('0'), &flags);
    avr_irq_t *uart_in = avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_INPUT);
    avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUTPUT), uart_output, NULL);
    avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUT_XOFF), uart_xoff, NULL);
    avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUT_XON), uart_xon, NULL);

    /* boot: run until Serial.begin() has turned the receiver on (RXEN0, bit 4 of UCSR0B at 0xC1) */
    while (!(avr->data[0xC1] & (1 << 4))) {
        int state = avr_run(avr);
        if (state == cpu_Done || state == cpu_Crashed || avr->cycle > FREQUENCY) {
            fprintf(stderr, "simavr_uart: the firmware did not open its serial port\n");
            return 1;
        }
    }
    const char *pty = open_pty();
    point_link(argv[2], pty);
    signal(SIGTERM, on_signal);
    signal(SIGINT, on_signal);
    signal(SIGPIPE, SIG_IGN);
    printf("ready %s\n", pty);
    fflush(stdout);

    pid_t parent = getppid();
    uint8_t pending[256];
    size_t n_pending = 0, next = 0;
    char text[128];
    size_t n_text = 0;
    struct pollfd fds[2] = {{.fd = master, .events = POLLIN}, {.fd = STDIN_FILENO, .events = POLLIN}};
    double t0 = now_s();
    avr_cycle_count_t c0 = avr->cycle;
    while (!stopping && getppid() == parent) {
        avr_cycle_count_t until = avr->cycle + SLICE_CYCLES;
        while (avr->cycle < until) {
            int state = avr_run(avr);
            if (state == cpu_Done || state == cpu_Crashed) {
                fprintf(stderr, "simavr_uart: the firmware stopped (state %d)\n", state);
                stopping = 1;
                break;
            }
            while (next < n_pending && !uart_full) avr_raise_irq(uart_in, pending[next++]);
        }
        /* no faster than real time: wait for the wall clock, or for a byte from the host */
        double ahead = (double)(avr->cycle - c0) / FREQUENCY - (now_s() - t0);
        if (ahead < -0.05) {  /* far behind (a loaded machine): forget the debt rather than sprint */
            t0 = now_s();
            c0 = avr->cycle;
            ahead = 0;
        }
        fds[0].fd = next < n_pending ? -1 : master;  /* read more only once the last bytes are in */
        if (poll(fds, 2, ahead > 0 ? (int)(ahead * 1000) : 0) <= 0) continue;
        if (fds[0].revents & POLLIN) {
            ssize_t r = read(master, pending, sizeof pending);
            if (r > 0) {
                n_pending = r;
                next = 0;
                if (rx_log >= 0 && write(rx_log, pending, r) != r) perror("write rx log");
            }
        }
        if (fds[1].revents & (POLLIN | POLLHUP)) {
            ssize_t r = read(STDIN_FILENO, text + n_text, sizeof text - 1 - n_text);
            if (r <= 0) {
                fds[1].fd = -1;  /* stdin closed: no more pin commands */
                continue;
            }
            n_text += r;
            text[n_text] = 0;
            char *end;
            while ((end = strchr(text, '\n'))) {
                *end = 0;
                pin_command(avr, text);
                memmove(text, end + 1, n_text - (end + 1 - text) + 1);
                n_text -= end + 1 - text;
            }
            if (n_text == sizeof text - 1) n_text = 0;  /* an overlong line: forget it */
        }
    }
    unlink(argv[2]);
    return 0;
}
