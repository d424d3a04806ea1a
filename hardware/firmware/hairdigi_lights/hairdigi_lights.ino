// hairdigi light board: reference firmware for an Arduino Uno / Nano (ATmega328P).
// Implements hardware/PROTOCOL.md version 1 over USB serial at 115200 8N1.
// Wiring: three LED drivers (e.g. constant-current MOSFET modules) on PWM pins 9, 10 and 11;
// an optional fault input per driver on pins 2, 3 and 4 (LOW = fault), with INPUT_PULLUP.

const uint8_t N_LIGHTS = 3;
const uint8_t PWM_PIN[N_LIGHTS] = {9, 10, 11};
const uint8_t FAULT_PIN[N_LIGHTS] = {2, 3, 4};
const char *FIRMWARE = "fw-1.0";
const uint8_t MAX_LINE = 32;

bool on[N_LIGHTS] = {false, false, false};
uint8_t intensity[N_LIGHTS] = {255, 255, 255};
char line[MAX_LINE + 2];
uint8_t len = 0;
bool overflow = false;

void apply(uint8_t n) { analogWrite(PWM_PIN[n], on[n] ? intensity[n] : 0); }

bool fault(uint8_t n) { return digitalRead(FAULT_PIN[n]) == LOW; }

void serialNumber(char *out) {  // a per-board id kept in EEPROM would go here
  strcpy(out, "UNO0001");
}

void reply(const char *text) { Serial.print(text); Serial.print('\n'); }

void handle(char *cmd) {
  char buf[64];
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
  } else if (cmd[0] == 'L' && cmd[1] != 0 && cmd[2] == ' ') {
    if (cmd[1] < '0' || cmd[1] >= '0' + N_LIGHTS) { reply("ERR E2 no such light"); return; }
    uint8_t n = cmd[1] - '0';
    const char *arg = cmd + 3;
    if (strcmp(arg, "ON") == 0 || strcmp(arg, "OFF") == 0) {
      if (arg[1] == 'N' && fault(n)) { reply("ERR E5 driver fault"); return; }
      on[n] = arg[1] == 'N';
      apply(n);
      reply("OK");
    } else if (arg[0] == 'I' && arg[1] == ' ') {
      char *end;
      long v = strtol(arg + 2, &end, 10);
      if (end == arg + 2 || *end != 0 || v < 0 || v > 255) { reply("ERR E3 value out of range"); return; }
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
    if (c == '\r') continue;
    if (c == '\n') {
      line[len] = 0;
      if (overflow) reply("ERR E4 line too long"); else handle(line);
      len = 0;
      overflow = false;
    } else if (len < MAX_LINE) {
      line[len++] = c;
    } else {
      overflow = true;
    }
  }
}
