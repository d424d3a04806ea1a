// hairdigi light board: reference firmware for an Arduino Uno / Nano (ATmega328P).
// Implements hardware/PROTOCOL.md version 1 over USB serial at 115200 8N1.
// Wiring: three LED drivers (e.g. constant-current MOSFET modules) on PWM pins 9, 10 and 11;
// an optional fault input per driver on pins 2, 3 and 4 (LOW = fault), with INPUT_PULLUP.
// Tested in the simavr AVR emulator against the Python simulator (tests/test_firmware.py).

const uint8_t N_LIGHTS = 3;
const uint8_t PWM_PIN[N_LIGHTS] = {9, 10, 11};
const uint8_t FAULT_PIN[N_LIGHTS] = {2, 3, 4};
const char *FIRMWARE = "fw-1.1";
const uint8_t MAX_LINE = 32;

bool on[N_LIGHTS] = {false, false, false};
uint8_t intensity[N_LIGHTS] = {255, 255, 255};
char line[MAX_LINE + 2];  // a command, the '\r' of a CRLF ending, and the terminating 0
uint8_t len = 0;
bool overflow = false;    // more than MAX_LINE + 1 bytes since the last '\n'

void apply(uint8_t n) { analogWrite(PWM_PIN[n], on[n] ? intensity[n] : 0); }

bool fault(uint8_t n) { return digitalRead(FAULT_PIN[n]) == LOW; }

void serialNumber(char *out) {  // a per-board id kept in EEPROM would go here
  strcpy(out, "UNO0001");
}

void reply(const char *text) { Serial.print(text); Serial.print('\n'); }

// True if every byte is printable ASCII (0x20 to 0x7E): no control character, no NUL, no 8-bit byte.
bool printable(const char *s, uint8_t n) {
  for (uint8_t i = 0; i < n; i++) {
    if ((uint8_t)s[i] < 0x20 || (uint8_t)s[i] > 0x7E) return false;
  }
  return true;
}

// A value written with ASCII digits only (no sign, no space; leading zeros allowed), or -1 when
// it is empty, not such a number, or over 255.
int parseValue(const char *s) {
  if (*s == 0) return -1;
  int v = 0;
  for (; *s; s++) {
    if (*s < '0' || *s > '9') return -1;
    v = v * 10 + (*s - '0');
    if (v > 255) return -1;
  }
  return v;
}

void handle(char *cmd) {
  char buf[64];
  const char *space = strchr(cmd, ' ');
  if (strcmp(cmd, "ID?") == 0) {
    char sn[16];
    serialNumber(sn);
    snprintf(buf, sizeof buf, "OK HAIRDIGI-LIGHTS 1 %s %s", FIRMWARE, sn);
    reply(buf);
  } else if (strcmp(cmd, "STATUS?") == 0) {
    snprintf(buf, sizeof buf, "OK %d:%d %d:%d %d:%d", on[0], intensity[0], on[1], intensity[1], on[2], intensity[2]);
    reply(buf);
  } else if (strcmp(cmd, "ALL OFF") == 0) {
    for (uint8_t n = 0; n < N_LIGHTS; n++) { on[n] = false; apply(n); }
    reply("OK");
  } else if (cmd[0] == 'L' && space != NULL) {
    // a light command: the index is everything between the 'L' and the first space
    if (space != cmd + 2 || cmd[1] < '0' || cmd[1] >= '0' + N_LIGHTS) { reply("ERR E2 no such light"); return; }
    uint8_t n = cmd[1] - '0';
    const char *arg = space + 1;
    if (strcmp(arg, "ON") == 0 || strcmp(arg, "OFF") == 0) {
      if (arg[1] == 'N' && fault(n)) { reply("ERR E5 driver fault"); return; }
      on[n] = arg[1] == 'N';
      apply(n);
      reply("OK");
    } else if (strncmp(arg, "I ", 2) == 0) {
      int v = parseValue(arg + 2);
      if (v < 0) { reply("ERR E3 value out of range"); return; }
      intensity[n] = (uint8_t)v;
      apply(n);
      reply("OK");
    } else {
      reply("ERR E1 unknown command");
    }
  } else {
    reply("ERR E1 unknown command");
  }
}

// A whole line has arrived (its '\n' is not stored): check its length and bytes, then carry it out.
void endLine() {
  if (len > 0 && line[len - 1] == '\r') len--;  // a CRLF line ending; any other '\r' is a stray byte
  line[len] = 0;
  if (overflow || len > MAX_LINE) reply("ERR E4 line too long");
  else if (!printable(line, len)) reply("ERR E1 unknown command");
  else handle(line);
  len = 0;
  overflow = false;
}

void setup() {
  for (uint8_t n = 0; n < N_LIGHTS; n++) {
    pinMode(PWM_PIN[n], OUTPUT);
    pinMode(FAULT_PIN[n], INPUT_PULLUP);
    apply(n);
  }
  Serial.begin(115200);
}

void loop() {
  while (Serial.available()) {
    char c = Serial.read();
    if (c == '\n') endLine();
    else if (len <= MAX_LINE) line[len++] = c;
    else overflow = true;
  }
}
