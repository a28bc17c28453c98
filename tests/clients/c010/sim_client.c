/* A low-level controller on Debian's Cyclone DDS 0.10.2 (the version inside Unitree's C++ SDK
 * and on the robots), used to check `ulab sim` the way Unitree's own stack would see it.
 *
 *   sim_client DOMAIN [INTERFACE]
 *
 * It configures its domain the way Unitree SDK2 does (only the network interface; everything
 * else Cyclone 0.10.2's default, which on `lo` means no multicast and unicast discovery on the
 * participant-index ports), subscribes hg LowState_ on rt/lowstate and publishes hg LowCmd_ on
 * rt/lowcmd, both with the idlc-generated types of hg_lowlevel.idl.
 *
 * 1. waits for LowState (bounded), then counts LowState over a 2 s window: Unitree CRC valid
 *    (computed here, see unitree_crc32), finite values, increasing ticks, and the spacing of the
 *    ticks (gcd of the deltas: the state period on the robot's clock); the wall-clock rate is
 *    reported, never judged;
 * 2. holds the current pose with PD on all 27 joints and moves the left elbow by +0.35 rad, for
 *    2.5 s of SIMULATED time (LowState tick), so that a simulator running slower than real time on
 *    a loaded machine gets the same time to move;
 * 3. keeps holding while also sending a command with a corrupted CRC that would move the left
 *    elbow 0.8 rad away, for 1.5 s of simulated time: the simulator must ignore it.
 * Prints progress lines and, last, one line `RESULT {json}`. Every wait is bounded (generous wall
 * limits that only turn a stalled peer into an error). Exit code 0 unless DDS itself failed (3)
 * or the arguments are wrong (2).
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include "dds/dds.h"
#include "dds/version.h"
#include "hg_lowlevel.h"

typedef unitree_hg_msg_dds__LowCmd_ LowCmd;
typedef unitree_hg_msg_dds__LowState_ LowState;

#define NUM_JOINTS 27
#define ELBOW 16 /* left_elbow_joint */

/* Unitree's CRC, from its published definition: CRC-32, polynomial 0x04C11DB7, seed 0xFFFFFFFF,
 * no reflection, no final xor, fed 32-bit words (little-endian in memory on the robot) from the
 * most significant bit, over the C struct image of the message without its trailing crc word. */
static uint32_t unitree_crc32(const uint32_t *words, size_t count)
{
  const uint32_t poly = 0x04C11DB7u;
  uint32_t crc = 0xFFFFFFFFu;
  for (size_t i = 0; i < count; i++) {
    uint32_t data = words[i];
    for (int bit = 31; bit >= 0; bit--) {
      uint32_t feedback = (crc >> 31) ^ ((data >> bit) & 1u);
      crc <<= 1;
      if (feedback) crc ^= poly;
    }
  }
  return crc;
}

/* The idlc-generated structs have the natural C layout Unitree hashes; callers zero them with
 * memset before filling so that padding bytes are zero. crc is the last member (4-aligned). */
static uint32_t lowcmd_crc(const LowCmd *c) { return unitree_crc32((const uint32_t *)c, sizeof *c / 4 - 1); }
static uint32_t lowstate_crc(const LowState *s) { return unitree_crc32((const uint32_t *)s, sizeof *s / 4 - 1); }

static double mono(void)
{
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return (double)ts.tv_sec + (double)ts.tv_nsec * 1e-9;
}

static void die(const char *what, dds_return_t rc)
{
  printf("ERROR %s: %s\n", what, dds_strretcode(rc));
  fflush(stdout);
  exit(3);
}

/* Running counts over received LowState; `window_*` are reset to measure one window. */
static struct {
  long total, total_crc_bad, total_nonfinite, tick_regressions;
  long window, window_crc_ok;
  uint32_t window_tick_gcd; /* gcd of tick deltas within the window */
  int have_latest;
  uint32_t last_tick;
  LowState latest;
} st;

static int all_finite(const LowState *s)
{
  const unitree_hg_msg_dds__IMUState_ *imu = &s->imu_state;
  for (int i = 0; i < 4; i++) if (!isfinite(imu->quaternion[i])) return 0;
  for (int i = 0; i < 3; i++)
    if (!isfinite(imu->gyroscope[i]) || !isfinite(imu->accelerometer[i]) || !isfinite(imu->rpy[i])) return 0;
  for (int i = 0; i < 35; i++) {
    const unitree_hg_msg_dds__MotorState_ *m = &s->motor_state[i];
    if (!isfinite(m->q) || !isfinite(m->dq) || !isfinite(m->ddq) || !isfinite(m->tau_est) || !isfinite(m->vol)) return 0;
  }
  return 1;
}

static void on_state(const LowState *s)
{
  int crc_ok = lowstate_crc(s) == s->crc;
  st.total++;
  st.window++;
  if (crc_ok) st.window_crc_ok++;
  else st.total_crc_bad++;
  if (!all_finite(s)) st.total_nonfinite++;
  if (st.have_latest && s->tick <= st.last_tick) st.tick_regressions++;
  if (st.have_latest && s->tick > st.last_tick && st.window > 1) {
    uint32_t a = st.window_tick_gcd, b = s->tick - st.last_tick;
    while (b) { uint32_t t = a % b; a = b; b = t; }
    st.window_tick_gcd = a;
  }
  st.last_tick = s->tick;
  st.latest = *s;
  st.have_latest = 1;
}

static dds_entity_t g_reader, g_waitset;

/* Takes every available LowState, one at a time into a zeroed buffer (so that the padding in
 * the struct image is zero, as the CRC definition requires). */
static void take_all(void)
{
  static LowState buf;
  for (;;) {
    void *samples[1] = {&buf};
    dds_sample_info_t info[1];
    memset(&buf, 0, sizeof buf);
    dds_return_t n = dds_take(g_reader, samples, info, 1, 1);
    if (n < 0) die("take", n);
    if (n == 0) return;
    if (info[0].valid_data) on_state(&buf);
  }
}

/* Receives LowState until `until` (monotonic seconds). */
static void pump_until(double until)
{
  for (;;) {
    take_all();
    double left = until - mono();
    if (left <= 0) return;
    dds_return_t rc = dds_waitset_wait(g_waitset, NULL, 0, (dds_duration_t)(left * 1e9));
    if (rc < 0) die("waitset_wait", rc);
  }
}

/* Gains of a standing hold (same as the Python SDK client test): legs stiff enough to stand. */
static void make_command(LowCmd *c, const float *targets, uint8_t mode_machine)
{
  static const float leg_kp[6] = {500, 500, 500, 500, 600, 600};
  static const float leg_kd[6] = {5, 5, 5, 6, 10, 10};
  memset(c, 0, sizeof *c);
  c->mode_pr = 0;
  c->mode_machine = mode_machine;
  for (int i = 0; i < NUM_JOINTS; i++) {
    unitree_hg_msg_dds__MotorCmd_ *m = &c->motor_cmd[i];
    m->mode = 1;
    m->q = targets[i];
    if (i < 12) { m->kp = leg_kp[i % 6]; m->kd = leg_kd[i % 6]; }
    else if (i == 12) { m->kp = 300; m->kd = 5; }
    else { m->kp = 120; m->kd = 3; }
  }
  c->crc = lowcmd_crc(c);
}

static void fmt_float(char *out, size_t n, double x)
{
  if (isfinite(x)) snprintf(out, n, "%.6f", x);
  else snprintf(out, n, "null");
}

int main(int argc, char **argv)
{
  if (argc < 2 || argc > 3) {
    fprintf(stderr, "usage: %s DOMAIN [INTERFACE]\n", argv[0]);
    return 2;
  }
  dds_domainid_t domain = (dds_domainid_t)strtoul(argv[1], NULL, 10);
  const char *iface = argc == 3 ? argv[2] : "lo";
  char config[512];
  /* What Unitree SDK2's ChannelFactory::Init(domain, interface) configures. */
  snprintf(config, sizeof config,
           "<CycloneDDS><Domain Id=\"any\"><General><Interfaces>"
           "<NetworkInterface name=\"%s\" priority=\"default\" multicast=\"default\"/>"
           "</Interfaces></General></Domain></CycloneDDS>", iface);

  dds_entity_t dom = dds_create_domain(domain, config);
  if (dom < 0) die("create_domain", dom);
  dds_entity_t pp = dds_create_participant(domain, NULL, NULL);
  if (pp < 0) die("create_participant", pp);
  dds_entity_t tstate = dds_create_topic(pp, &unitree_hg_msg_dds__LowState__desc, "rt/lowstate", NULL, NULL);
  if (tstate < 0) die("create_topic lowstate", tstate);
  dds_entity_t tcmd = dds_create_topic(pp, &unitree_hg_msg_dds__LowCmd__desc, "rt/lowcmd", NULL, NULL);
  if (tcmd < 0) die("create_topic lowcmd", tcmd);
  /* Best effort like the SDK's reader; a deeper history than the SDK's 1 so that a scheduling
   * hiccup of this polling loop does not show up as a lower LowState rate. */
  dds_qos_t *rq = dds_create_qos();
  dds_qset_reliability(rq, DDS_RELIABILITY_BEST_EFFORT, 0);
  dds_qset_history(rq, DDS_HISTORY_KEEP_LAST, 64);
  g_reader = dds_create_reader(pp, tstate, rq, NULL);
  dds_delete_qos(rq);
  if (g_reader < 0) die("create_reader", g_reader);
  dds_entity_t wr = dds_create_writer(pp, tcmd, NULL, NULL); /* SDK default: reliable, keep last 1 */
  if (wr < 0) die("create_writer", wr);
  dds_entity_t rc_cond = dds_create_readcondition(g_reader, DDS_ANY_STATE);
  if (rc_cond < 0) die("create_readcondition", rc_cond);
  g_waitset = dds_create_waitset(pp);
  if (g_waitset < 0) die("create_waitset", g_waitset);
  dds_return_t rc = dds_waitset_attach(g_waitset, rc_cond, 0);
  if (rc < 0) die("waitset_attach", rc);
  printf("READY domain=%u version=%s\n", (unsigned)domain, DDS_VERSION);
  fflush(stdout);

  /* 1. State stream. */
  double deadline = mono() + 20.0;
  while (!st.have_latest && mono() < deadline) pump_until(mono() + 0.05);
  if (!st.have_latest) {
    printf("RESULT {\"error\":\"no LowState received\",\"version\":\"%s\"}\n", DDS_VERSION);
    fflush(stdout);
    dds_delete(dom);
    return 0;
  }
  pump_until(mono() + 0.3);
  st.window = st.window_crc_ok = 0;
  st.window_tick_gcd = 0;
  long regressions_before = st.tick_regressions;
  double t0 = mono();
  pump_until(t0 + 2.0);
  double elapsed = mono() - t0;
  long window = st.window, window_crc_ok = st.window_crc_ok;
  int ticks_increasing = st.tick_regressions == regressions_before;
  uint32_t tick_gcd = st.window_tick_gcd;
  uint8_t mode_machine = st.latest.mode_machine;
  printf("STATES window=%ld crc_ok=%ld rate=%.1f\n", window, window_crc_ok, window / elapsed);
  fflush(stdout);

  /* 2. Hold the current pose, move the left elbow. */
  float start[NUM_JOINTS], targets[NUM_JOINTS];
  for (int i = 0; i < NUM_JOINTS; i++) start[i] = targets[i] = st.latest.motor_state[i].q;
  targets[ELBOW] = start[ELBOW] + 0.35f;
  static LowCmd hold, corrupt;
  make_command(&hold, targets, mode_machine);
  long writes = 0;
  double next = mono();
  double give_up = next + 120.0;
  uint32_t tick0 = st.latest.tick;
  while (st.latest.tick - tick0 < 2500 && mono() < give_up) {
    if ((rc = dds_write(wr, &hold)) < 0) die("write", rc);
    writes++;
    next += 0.002;
    pump_until(next);
  }
  float moved = st.latest.motor_state[ELBOW].q;
  uint32_t hold_ms = st.latest.tick - tick0;
  printf("MOVED elbow start=%.4f target=%.4f final=%.4f\n", start[ELBOW], targets[ELBOW], moved);
  fflush(stdout);

  /* 3. Valid hold commands interleaved with a corrupted-CRC command far away. */
  float bad[NUM_JOINTS];
  memcpy(bad, targets, sizeof bad);
  bad[ELBOW] = targets[ELBOW] - 0.8f;
  make_command(&corrupt, bad, mode_machine);
  corrupt.crc ^= 1u;
  long corrupt_writes = 0;
  next = mono();
  give_up = next + 120.0;
  tick0 = st.latest.tick;
  while (st.latest.tick - tick0 < 1500 && mono() < give_up) {
    if ((rc = dds_write(wr, &hold)) < 0) die("write", rc);
    if ((rc = dds_write(wr, &corrupt)) < 0) die("write", rc);
    writes++;
    corrupt_writes++;
    next += 0.004;
    pump_until(next);
  }
  float after = st.latest.motor_state[ELBOW].q;
  uint32_t corrupt_ms = st.latest.tick - tick0;

  char f[8][32];
  fmt_float(f[0], sizeof f[0], start[ELBOW]);
  fmt_float(f[1], sizeof f[1], targets[ELBOW]);
  fmt_float(f[2], sizeof f[2], moved);
  fmt_float(f[3], sizeof f[3], bad[ELBOW]);
  fmt_float(f[4], sizeof f[4], after);
  fmt_float(f[5], sizeof f[5], st.latest.imu_state.rpy[0]);
  fmt_float(f[6], sizeof f[6], st.latest.imu_state.rpy[1]);
  fmt_float(f[7], sizeof f[7], window / elapsed);
  printf("RESULT {\"version\":\"%s\",\"rate_hz\":%s,\"states\":%ld,\"crc_ok\":%ld,"
         "\"ticks_increasing\":%s,\"tick_gcd_ms\":%u,\"hold_ms\":%u,\"corrupt_ms\":%u,\"mode_machine\":%u,"
         "\"total_states\":%ld,\"total_crc_bad\":%ld,\"total_nonfinite\":%ld,\"tick_regressions\":%ld,"
         "\"valid_writes\":%ld,\"corrupt_writes\":%ld,"
         "\"move\":{\"slot\":%d,\"start\":%s,\"target\":%s,\"final\":%s},"
         "\"corrupted\":{\"slot\":%d,\"held_target\":%s,\"corrupt_target\":%s,\"final\":%s},"
         "\"rpy\":[%s,%s]}\n",
         DDS_VERSION, f[7], window, window_crc_ok, ticks_increasing ? "true" : "false", (unsigned)tick_gcd,
         (unsigned)hold_ms, (unsigned)corrupt_ms, (unsigned)mode_machine,
         st.total, st.total_crc_bad, st.total_nonfinite, st.tick_regressions, writes, corrupt_writes,
         ELBOW, f[0], f[1], f[2], ELBOW, f[1], f[3], f[4], f[5], f[6]);
  fflush(stdout);
  dds_delete(dom);
  return 0;
}
