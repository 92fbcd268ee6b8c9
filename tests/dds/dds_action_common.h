/* What dds_action_client.c and dds_action_server.c share: the program's one participant, and its
   topics, writers and readers as rmw_cyclonedds makes them (reliable, no type information). For
   single-file programs: everything here is static. */
#ifndef HORUS_TESTS_DDS_ACTION_COMMON_H
#define HORUS_TESTS_DDS_ACTION_COMMON_H

#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "dds/dds.h"

static dds_entity_t participant;

static inline dds_qos_t *reliable(bool transient_local)
{
  dds_qos_t *qos = dds_create_qos();
  dds_qset_reliability(qos, DDS_RELIABILITY_RELIABLE, DDS_SECS(1));
  dds_qset_history(qos, DDS_HISTORY_KEEP_LAST, 100);
  if (transient_local) dds_qset_durability(qos, DDS_DURABILITY_TRANSIENT_LOCAL);
  return qos;
}

/* A topic of `type` carried under the DDS type name `name` and no type information, as
   rmw_cyclonedds's samples are. The descriptor is kept for the topic's life. */
static inline dds_entity_t topic_named(const dds_topic_descriptor_t *type, const char *name,
                                       const char *topic)
{
  /* The descriptor's members are const: a copy in memory of its own, changed through casts. */
  dds_topic_descriptor_t *renamed = malloc(sizeof *renamed);
  memcpy(renamed, type, sizeof *renamed);
  renamed->m_typename = strdup(name);
  *(uint32_t *)&renamed->m_flagset = type->m_flagset & ~(uint32_t)DDS_TOPIC_XTYPES_METADATA;
  renamed->type_information.data = NULL;
  renamed->type_information.sz = 0;
  renamed->type_mapping.data = NULL;
  renamed->type_mapping.sz = 0;
  dds_entity_t made = dds_create_topic(participant, renamed, topic, NULL, NULL);
  if (made < 0)
  {
    fprintf(stderr, "topic %s: %s\n", topic, dds_strretcode(made));
    exit(1);
  }
  return made;
}

static inline dds_entity_t writer_of(dds_entity_t topic)
{
  dds_qos_t *qos = reliable(false);
  dds_entity_t made = dds_create_writer(participant, topic, qos, NULL);
  dds_delete_qos(qos);
  return made;
}

static inline dds_entity_t reader_of(dds_entity_t topic, bool transient_local)
{
  dds_qos_t *qos = reliable(transient_local);
  dds_entity_t made = dds_create_reader(participant, topic, qos, NULL);
  dds_delete_qos(qos);
  return made;
}

static inline bool matched(dds_entity_t entity, bool writer)
{
  if (writer)
  {
    dds_publication_matched_status_t status;
    return dds_get_publication_matched_status(entity, &status) == 0 && status.current_count > 0;
  }
  dds_subscription_matched_status_t status;
  return dds_get_subscription_matched_status(entity, &status) == 0 && status.current_count > 0;
}

#endif
