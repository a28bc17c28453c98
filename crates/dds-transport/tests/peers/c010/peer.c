/* Interop test peer on Debian's Cyclone DDS 0.10.2, standing in for Unitree's own stack.
 *
 * It configures its participant the way Unitree SDK2 does (only the network interface, everything
 * else Cyclone's default) and uses default QoS on every endpoint, as the SDK does.
 *
 * usage: peer DOMAIN INTERFACE SECONDS                      robot side
 *        peer DOMAIN INTERFACE SECONDS controller J Q KP KD  controller side
 *
 * Robot side: publishes hg LowState_ on rt/lowstate at 100 Hz (CRC sealed), subscribes hg LowCmd_
 * on rt/lowcmd. Every received command is printed (with its CRC check) and echoed into the next
 * states: motor_state[i].q = motor_cmd[i].q, reserve[0] = commands received, reserve[1] = crc of
 * the last command, reserve[2] = number of commands whose CRC was valid. A command with
 * reserve[0] == 0xDEADBEEF makes it exit (the tests' shutdown request).
 *
 * Controller side (like a Unitree SDK2 low-level client): subscribes rt/lowstate and checks each
 * state's CRC and tick; publishes LowCmd_ at 500 Hz (CRC sealed, mode_machine copied from the
 * state) driving motor J to position Q with gains KP/KD, all other motors mode 0. Prints a JSON
 * summary at the end.
 *
 * Exit: 0 after SECONDS (or on shutdown), 3 on a setup error.
 * CRC: Unitree's word-wise CRC-32 (polynomial 0x04C11DB7, init 0xFFFFFFFF, no reflection, no final
 * xor) over the C struct image except its last word (the crc member), as in Unitree's SDK examples.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "dds/dds.h"
#include "dds/version.h"
#include "unitree_hg.h"

static const char *CONFIG_FMT =
    "<CycloneDDS><Domain Id=\"any\"><General><Interfaces>"
    "<NetworkInterface name=\"%s\" priority=\"default\" multicast=\"default\"/>"
    "</Interfaces></General></Domain></CycloneDDS>";

static void die(const char *what, dds_return_t rc)
{
  printf("ERROR %s: %s\n", what, dds_strretcode(rc));
  fflush(stdout);
  exit(3);
}

static uint32_t crc32_core(const uint32_t *ptr, uint32_t len)
{
  uint32_t crc = 0xFFFFFFFFu;
  const uint32_t poly = 0x04C11DB7u;
  for (uint32_t i = 0; i < len; i++) {
    uint32_t xbit = 1u << 31;
    uint32_t data = ptr[i];
    for (uint32_t bits = 0; bits < 32; bits++) {
      if (crc & 0x80000000u) {
        crc <<= 1;
        crc ^= poly;
      } else {
        crc <<= 1;
      }
      if (data & xbit) crc ^= poly;
      xbit >>= 1;
    }
  }
  return crc;
}

/* The C struct images: padding must be zero, as in a value-initialized C++ message. */
static uint32_t cmd_crc(const unitree_hg_msg_dds__LowCmd_ *c)
{
  return crc32_core((const uint32_t *)c, (uint32_t)(sizeof *c / 4 - 1));
}
static uint32_t state_crc(const unitree_hg_msg_dds__LowState_ *s)
{
  return crc32_core((const uint32_t *)s, (uint32_t)(sizeof *s / 4 - 1));
}

static dds_entity_t dom, pp;

static void setup(dds_domainid_t domain, const char *iface)
{
  char config[1024];
  snprintf(config, sizeof config, CONFIG_FMT, iface);
  dom = dds_create_domain(domain, config);
  if (dom < 0) die("create_domain", dom);
  pp = dds_create_participant(domain, NULL, NULL);
  if (pp < 0) die("create_participant", pp);
}

static int robot(double seconds)
{
  dds_entity_t tcmd = dds_create_topic(pp, &unitree_hg_msg_dds__LowCmd__desc, "rt/lowcmd", NULL, NULL);
  if (tcmd < 0) die("create_topic lowcmd", tcmd);
  dds_entity_t tstate = dds_create_topic(pp, &unitree_hg_msg_dds__LowState__desc, "rt/lowstate", NULL, NULL);
  if (tstate < 0) die("create_topic lowstate", tstate);
  dds_entity_t rd = dds_create_reader(pp, tcmd, NULL, NULL);
  if (rd < 0) die("create_reader", rd);
  dds_entity_t wr = dds_create_writer(pp, tstate, NULL, NULL);
  if (wr < 0) die("create_writer", wr);
  printf("READY version=%s\n", DDS_VERSION);
  fflush(stdout);

  static unitree_hg_msg_dds__LowState_ state;
  static unitree_hg_msg_dds__LowCmd_ cmd;
  memset(&state, 0, sizeof state);
  state.mode_machine = 6;
  state.imu_state.quaternion[0] = 1.0f;
  uint32_t received = 0, crc_ok = 0;
  int matched_reported = 0;
  dds_time_t end = dds_time() + (dds_time_t)(seconds * 1e9);
  while (dds_time() < end) {
    void *samples[1] = {&cmd};
    dds_sample_info_t info[1];
    dds_return_t n;
    while ((n = dds_take(rd, samples, info, 1, 1)) > 0) {
      if (!info[0].valid_data) continue;
      if (cmd.reserve[0] == 0xDEADBEEFu) {
        printf("SHUTDOWN received=%u crc_ok=%u\n", received, crc_ok);
        fflush(stdout);
        dds_delete(dom);
        return 0;
      }
      received++;
      int ok = cmd_crc(&cmd) == cmd.crc;
      crc_ok += ok;
      for (int i = 0; i < 35; i++) state.motor_state[i].q = cmd.motor_cmd[i].q;
      state.reserve[0] = received;
      state.reserve[1] = cmd.crc;
      state.reserve[2] = crc_ok;
      printf("CMD n=%u mode_pr=%u mode_machine=%u m0.mode=%u m0.q=%.6f m0.kp=%.3f m34.q=%.6f crc=%u crc_ok=%d\n",
             received, cmd.mode_pr, cmd.mode_machine, cmd.motor_cmd[0].mode, cmd.motor_cmd[0].q,
             cmd.motor_cmd[0].kp, cmd.motor_cmd[34].q, cmd.crc, ok);
      fflush(stdout);
    }
    if (n < 0) die("take", n);
    if (!matched_reported) {
      dds_publication_matched_status_t pm;
      if (dds_get_publication_matched_status(wr, &pm) == 0 && pm.current_count > 0) {
        printf("MATCHED reader_count=%u\n", pm.current_count);
        fflush(stdout);
        matched_reported = 1;
      }
    }
    state.tick += 10;
    state.crc = state_crc(&state);
    dds_return_t rc = dds_write(wr, &state);
    if (rc < 0) die("write", rc);
    dds_sleepfor(DDS_MSECS(10));
  }
  printf("DONE received=%u crc_ok=%u ticks=%u\n", received, crc_ok, state.tick);
  fflush(stdout);
  dds_delete(dom);
  return 0;
}

static int controller(double seconds, int joint, float q, float kp, float kd)
{
  if (joint < 0 || joint >= 35) {
    fprintf(stderr, "joint out of range\n");
    return 2;
  }
  dds_entity_t tcmd = dds_create_topic(pp, &unitree_hg_msg_dds__LowCmd__desc, "rt/lowcmd", NULL, NULL);
  if (tcmd < 0) die("create_topic lowcmd", tcmd);
  dds_entity_t tstate = dds_create_topic(pp, &unitree_hg_msg_dds__LowState__desc, "rt/lowstate", NULL, NULL);
  if (tstate < 0) die("create_topic lowstate", tstate);
  dds_entity_t rd = dds_create_reader(pp, tstate, NULL, NULL);
  if (rd < 0) die("create_reader", rd);
  dds_entity_t wr = dds_create_writer(pp, tcmd, NULL, NULL);
  if (wr < 0) die("create_writer", wr);
  printf("READY version=%s\n", DDS_VERSION);
  fflush(stdout);

  static unitree_hg_msg_dds__LowState_ state;
  static unitree_hg_msg_dds__LowCmd_ cmd;
  memset(&cmd, 0, sizeof cmd);
  uint64_t states = 0, crc_ok = 0, cmds = 0;
  int have_state = 0, ticks_increasing = 1;
  uint32_t last_tick = 0, first_tick = 0;
  dds_time_t first_t = 0, last_t = 0;
  float first_q = 0.0f, last_q = 0.0f;
  dds_time_t end = dds_time() + (dds_time_t)(seconds * 1e9);
  while (dds_time() < end) {
    void *samples[1] = {&state};
    dds_sample_info_t info[1];
    dds_return_t n;
    while ((n = dds_take(rd, samples, info, 1, 1)) > 0) {
      if (!info[0].valid_data) continue;
      states++;
      crc_ok += state_crc(&state) == state.crc;
      dds_time_t now = dds_time();
      if (!have_state) {
        first_tick = state.tick;
        first_t = now;
        first_q = state.motor_state[joint].q;
      } else if (state.tick <= last_tick) {
        ticks_increasing = 0;
      }
      have_state = 1;
      last_tick = state.tick;
      last_t = now;
      last_q = state.motor_state[joint].q;
      cmd.mode_machine = state.mode_machine;
    }
    if (n < 0) die("take", n);
    if (have_state) {
      for (int i = 0; i < 35; i++) cmd.motor_cmd[i].mode = 0;
      cmd.mode_pr = 0;
      cmd.motor_cmd[joint].mode = 1;
      cmd.motor_cmd[joint].q = q;
      cmd.motor_cmd[joint].dq = 0.0f;
      cmd.motor_cmd[joint].tau = 0.0f;
      cmd.motor_cmd[joint].kp = kp;
      cmd.motor_cmd[joint].kd = kd;
      cmd.crc = cmd_crc(&cmd);
      dds_return_t rc = dds_write(wr, &cmd);
      if (rc < 0) die("write", rc);
      cmds++;
    }
    dds_sleepfor(DDS_USECS(2000));
  }
  double span = (double)(last_t - first_t) / 1e9;
  printf("{\"states\": %llu, \"crc_ok\": %llu, \"rate_hz\": %.1f, \"ticks_increasing\": %s, \"first_tick\": %u, "
         "\"last_tick\": %u, \"commands\": %llu, \"joint\": %d, \"first_q\": %.6f, \"last_q\": %.6f}\n",
         (unsigned long long)states, (unsigned long long)crc_ok, span > 0 ? (double)(states - 1) / span : 0.0,
         ticks_increasing ? "true" : "false", first_tick, last_tick, (unsigned long long)cmds, joint, first_q, last_q);
  fflush(stdout);
  dds_delete(dom);
  return 0;
}

int main(int argc, char **argv)
{
  if (argc != 4 && argc != 9) {
    fprintf(stderr, "usage: %s DOMAIN INTERFACE SECONDS [controller JOINT Q KP KD]\n", argv[0]);
    return 2;
  }
  dds_domainid_t domain = (dds_domainid_t)strtoul(argv[1], NULL, 10);
  if (domain == 0) {
    fprintf(stderr, "refusing domain 0 (a real robot's)\n");
    return 2;
  }
  double seconds = strtod(argv[3], NULL);
  setup(domain, argv[2]);
  if (argc == 9 && strcmp(argv[4], "controller") == 0)
    return controller(seconds, atoi(argv[5]), strtof(argv[6], NULL), strtof(argv[7], NULL), strtof(argv[8], NULL));
  return robot(seconds);
}
