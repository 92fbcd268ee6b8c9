/* A hostile DDS participant, built with idlc from attacker_idl/attack.idl: it writes types of
   other layouts under horus.msg.CmdVel's DDS type name on rt/cmd_vel, as a careless or malicious
   program on the same DDS domain could.
     dds_attacker same-size DOMAIN N   N attack::SameSize samples (CmdVel's 16 bytes; stamp_nanos
                                       = 1000000 + i, angular = -7)
     dds_attacker longer DOMAIN N      N attack::Longer samples (CmdVel and 8 bytes more)
     dds_attacker shorter DOMAIN N     N attack::Shorter samples (CmdVel cut short: 12 bytes)
   Option --untyped: the writer announces no XTypes type information (as a ROS 2 node's rmw
   does), so DDS can only compare type names. Option --writers K: K writers (K GUIDs), each
   writing the N samples in turn with the others (N * K in all).
   It writes once it has seen a reader of rt/cmd_vel (whether or not DDS matches it with that
   reader), 2 ms apart, then waits up to 10 s for the matched readers to acknowledge them, and
   prints "wrote N" (N * K). A timeout (20 s) finding a reader is exit status 1. */
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "attack.h"
#include "dds/dds.h"

#define MAX_WRITERS 64

static bool reader_seen(dds_entity_t subscriptions)
{
  void *samples[16] = { NULL };
  dds_sample_info_t infos[16];
  bool seen = false;
  int count = dds_read(subscriptions, samples, infos, 16, 16);
  for (int i = 0; i < count; i++)
  {
    const dds_builtintopic_endpoint_t *reader = samples[i];
    if (infos[i].valid_data && strcmp(reader->topic_name, "rt/cmd_vel") == 0)
      seen = true;
  }
  if (count > 0)
    dds_return_loan(subscriptions, samples, count);
  return seen;
}

int main(int argc, char **argv)
{
  bool untyped = false;
  int writers = 1;
  int kept = 1;
  for (int i = 1; i < argc; i++)
  {
    if (strcmp(argv[i], "--untyped") == 0)
      untyped = true;
    else if (strcmp(argv[i], "--writers") == 0 && i + 1 < argc)
      writers = atoi(argv[++i]);
    else
      argv[kept++] = argv[i];
  }
  const dds_topic_descriptor_t *type = NULL;
  if (kept == 4 && strcmp(argv[1], "same-size") == 0)
    type = &attack_SameSize_desc;
  else if (kept == 4 && strcmp(argv[1], "longer") == 0)
    type = &attack_Longer_desc;
  else if (kept == 4 && strcmp(argv[1], "shorter") == 0)
    type = &attack_Shorter_desc;
  if (type == NULL || writers < 1 || writers > MAX_WRITERS)
  {
    fprintf(stderr, "usage: dds_attacker same-size|longer|shorter DOMAIN N [--untyped] "
                    "[--writers K (1 to %d)]\n", MAX_WRITERS);
    return 2;
  }
  const int count = atoi(argv[3]);
  /* idlc's descriptor under CmdVel's type name, and without its type information if untyped. */
  const dds_topic_descriptor_t descriptor = {
    .m_size = type->m_size, .m_align = type->m_align,
    .m_flagset = untyped ? type->m_flagset & ~DDS_TOPIC_XTYPES_METADATA : type->m_flagset,
    .m_nkeys = type->m_nkeys, .m_typename = "horus::msg::dds_::CmdVel_", .m_keys = type->m_keys,
    .m_nops = type->m_nops, .m_ops = type->m_ops, .m_meta = type->m_meta,
    .type_information = type->type_information, .type_mapping = type->type_mapping,
    .restrict_data_representation = type->restrict_data_representation,
  };
  dds_entity_t participant = dds_create_participant((dds_domainid_t) atoi(argv[2]), NULL, NULL);
  dds_entity_t topic = dds_create_topic(participant, &descriptor, "rt/cmd_vel", NULL, NULL);
  dds_qos_t *qos = dds_create_qos();
  dds_qset_reliability(qos, DDS_RELIABILITY_RELIABLE, DDS_SECS(1));
  dds_qset_history(qos, DDS_HISTORY_KEEP_ALL, 0);
  dds_entity_t writer[MAX_WRITERS];
  bool made = true;
  for (int w = 0; w < writers; w++)
  {
    writer[w] = dds_create_writer(participant, topic, qos, NULL);
    made = made && writer[w] >= 0;
  }
  dds_delete_qos(qos);
  dds_entity_t subscriptions =
      dds_create_reader(participant, DDS_BUILTIN_TOPIC_DCPSSUBSCRIPTION, NULL, NULL);
  if (participant < 0 || topic < 0 || !made || subscriptions < 0)
  {
    fprintf(stderr, "dds_attacker: cannot create its DDS entities\n");
    return 1;
  }
  printf("ready\n");
  fflush(stdout);
  int waited = 0;
  while (!reader_seen(subscriptions))
  {
    if (++waited > 2000)
    {
      fprintf(stderr, "dds_attacker: no reader of rt/cmd_vel\n");
      return 1;
    }
    dds_sleepfor(DDS_MSECS(10));
  }
  dds_sleepfor(DDS_MSECS(500)); /* the reader's side of a match, when DDS makes one */
  for (int i = 0; i < count; i++)
  {
    attack_SameSize same = { .stamp_nanos = 1000000u + (uint64_t) i, .angular = -7.0f };
    attack_Longer longer = { .stamp_nanos = 1000000u + (uint64_t) i, .linear = 3.0f,
                             .angular = -7.0f, .extra = (uint64_t) i };
    attack_Shorter shorter = { .stamp_nanos = 1000000u + (uint64_t) i, .linear = 3.0f };
    const void *sample = type == &attack_SameSize_desc ? (const void *) &same
                         : type == &attack_Longer_desc ? (const void *) &longer
                                                       : (const void *) &shorter;
    for (int w = 0; w < writers; w++)
    {
      dds_return_t code = dds_write(writer[w], sample);
      if (code < 0)
      {
        fprintf(stderr, "dds_attacker: write: %s\n", dds_strretcode(code));
        return 1;
      }
    }
    dds_sleepfor(DDS_MSECS(2));
  }
  for (int w = 0; w < writers; w++)
    dds_wait_for_acks(writer[w], DDS_SECS(10));
  printf("wrote %d\n", count * writers);
  fflush(stdout);
  dds_delete(participant);
  return 0;
}
