/* Interop test peer on Debian's Cyclone DDS 0.10.2, standing in for Unitree's own stack.
 *
 * It configures its participant the way Unitree SDK2 does (only the network interface, everything
 * else Cyclone's default), publishes hg LowState_ on rt/lowstate at 100 Hz and subscribes hg
 * LowCmd_ on rt/lowcmd with default QoS. Every received command is printed and echoed into the
 * next states: motor_state[i].q = motor_cmd[i].q, reserve[0] = number of commands received,
 * reserve[1] = crc of the last command. It exits 0 after SECONDS, or as soon as a command with
 * reserve[0] == 0xDEADBEEF arrives (the test's shutdown request), or 3 on a setup error.
 *
 * usage: peer DOMAIN INTERFACE SECONDS
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

int main(int argc, char **argv)
{
  if (argc != 4) {
    fprintf(stderr, "usage: %s DOMAIN INTERFACE SECONDS\n", argv[0]);
    return 2;
  }
  dds_domainid_t domain = (dds_domainid_t)strtoul(argv[1], NULL, 10);
  double seconds = strtod(argv[3], NULL);
  char config[1024];
  snprintf(config, sizeof config, CONFIG_FMT, argv[2]);

  dds_entity_t dom = dds_create_domain(domain, config);
  if (dom < 0) die("create_domain", dom);
  dds_entity_t pp = dds_create_participant(domain, NULL, NULL);
  if (pp < 0) die("create_participant", pp);
  dds_entity_t tcmd = dds_create_topic(pp, &unitree_hg_msg_dds__LowCmd__desc, "rt/lowcmd", NULL, NULL);
  if (tcmd < 0) die("create_topic lowcmd", tcmd);
  dds_entity_t tstate = dds_create_topic(pp, &unitree_hg_msg_dds__LowState__desc, "rt/lowstate", NULL, NULL);
  if (tstate < 0) die("create_topic lowstate", tstate);
  dds_entity_t rd = dds_create_reader(pp, tcmd, NULL, NULL);
  if (rd < 0) die("create_reader", rd);
  dds_entity_t wr = dds_create_writer(pp, tstate, NULL, NULL);
  if (wr < 0) die("create_writer", wr);
  printf("READY domain=%u version=%s\n", (unsigned)domain, DDS_VERSION);
  fflush(stdout);

  static unitree_hg_msg_dds__LowState_ state;
  static unitree_hg_msg_dds__LowCmd_ cmd;
  memset(&state, 0, sizeof state);
  state.mode_machine = 6;
  state.imu_state.quaternion[0] = 1.0f;
  uint32_t received = 0;
  int matched_reported = 0;
  dds_time_t end = dds_time() + (dds_time_t)(seconds * 1e9);
  while (dds_time() < end) {
    void *samples[1] = {&cmd};
    dds_sample_info_t info[1];
    dds_return_t n;
    while ((n = dds_take(rd, samples, info, 1, 1)) > 0) {
      if (!info[0].valid_data) continue;
      if (cmd.reserve[0] == 0xDEADBEEFu) {
        printf("SHUTDOWN received=%u\n", received);
        fflush(stdout);
        dds_delete(dom);
        return 0;
      }
      received++;
      for (int i = 0; i < 35; i++) state.motor_state[i].q = cmd.motor_cmd[i].q;
      state.reserve[0] = received;
      state.reserve[1] = cmd.crc;
      printf("CMD n=%u mode_pr=%u mode_machine=%u m0.mode=%u m0.q=%.6f m0.kp=%.3f m34.q=%.6f crc=%u\n",
             received, cmd.mode_pr, cmd.mode_machine, cmd.motor_cmd[0].mode, cmd.motor_cmd[0].q,
             cmd.motor_cmd[0].kp, cmd.motor_cmd[34].q, cmd.crc);
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
    dds_return_t rc = dds_write(wr, &state);
    if (rc < 0) die("write", rc);
    dds_sleepfor(DDS_MSECS(10));
  }
  printf("DONE received=%u ticks=%u\n", received, state.tick);
  fflush(stdout);
  dds_delete(dom);
  return 0;
}
