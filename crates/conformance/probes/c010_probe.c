/* Interop probe of `ulab conform` on Cyclone DDS 0.10.2 (Debian's libddsc, the version in Unitree's SDK and robots).
 *
 * It joins the domain exactly as Unitree's SDK2 does (only the network interface configured, everything else
 * Cyclone's default, default QoS on its reader) and subscribes rt/lowstate with the idlc-generated hg LowState_
 * type, as a Unitree low-level controller would.
 *
 * usage: c010_probe DOMAIN INTERFACE SECONDS MIN_SAMPLES
 *
 * Prints `READY version=...`, then one JSON line when it has received MIN_SAMPLES samples or SECONDS have passed:
 *   {"version": "0.10.2", "matched_writers": N, "samples": N, "first_sample_ms": T, "elapsed_ms": T}
 * (matched_writers: writers of rt/lowstate it discovered and matched). Exit 0; 2 on bad arguments; 3 on a DDS
 * error. A crash on the peer's discovery data shows as a signal (the parent reads the exit status).
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "dds/dds.h"
#include "dds/version.h"
#include "lowstate.h"

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
  if (argc != 5) {
    fprintf(stderr, "usage: %s DOMAIN INTERFACE SECONDS MIN_SAMPLES\n", argv[0]);
    return 2;
  }
  dds_domainid_t domain = (dds_domainid_t)strtoul(argv[1], NULL, 10);
  double seconds = strtod(argv[3], NULL);
  long min_samples = strtol(argv[4], NULL, 10);
  if (seconds <= 0.0 || min_samples < 1) {
    fprintf(stderr, "SECONDS and MIN_SAMPLES must be positive\n");
    return 2;
  }
  char config[1024];
  snprintf(config, sizeof config, CONFIG_FMT, argv[2]);
  dds_entity_t dom = dds_create_domain(domain, config);
  if (dom < 0) die("create_domain", dom);
  dds_entity_t pp = dds_create_participant(domain, NULL, NULL);
  if (pp < 0) die("create_participant", pp);
  dds_entity_t topic = dds_create_topic(pp, &unitree_hg_msg_dds__LowState__desc, "rt/lowstate", NULL, NULL);
  if (topic < 0) die("create_topic", topic);
  dds_entity_t rd = dds_create_reader(pp, topic, NULL, NULL);
  if (rd < 0) die("create_reader", rd);
  printf("READY version=%s\n", DDS_VERSION);
  fflush(stdout);

  static unitree_hg_msg_dds__LowState_ state;
  long samples = 0;
  dds_time_t start = dds_time(), first = 0;
  dds_time_t end = start + (dds_time_t)(seconds * 1e9);
  uint32_t matched = 0;
  while (dds_time() < end && samples < min_samples) {
    void *buf[1] = {&state};
    dds_sample_info_t info[1];
    dds_return_t n;
    while ((n = dds_take(rd, buf, info, 1, 1)) > 0) {
      if (!info[0].valid_data) continue;
      if (samples == 0) first = dds_time();
      samples++;
    }
    if (n < 0) die("take", n);
    dds_subscription_matched_status_t sm;
    if (dds_get_subscription_matched_status(rd, &sm) == 0 && sm.current_count > matched) matched = sm.current_count;
    dds_sleepfor(DDS_MSECS(2));
  }
  printf("{\"version\": \"%s\", \"matched_writers\": %u, \"samples\": %ld, \"first_sample_ms\": %.1f, \"elapsed_ms\": %.1f}\n",
         DDS_VERSION, matched, samples, samples > 0 ? (double)(first - start) / 1e6 : -1.0,
         (double)(dds_time() - start) / 1e6);
  fflush(stdout);
  dds_delete(dom);
  return 0;
}
