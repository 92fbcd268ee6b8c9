/* A plain Cyclone DDS program built with idlc from the IDL horus-gen emits and from ROS 2's
   messages as hand-written IDL (tools/horus/ros2_idl/; the tests build it), standing in for a
   ROS 2 node: it knows nothing of HORUS but the IDL.
     dds_peer read-cmdvel DOMAIN N   prints N horus.msg.CmdVel samples of rt/cmd_vel, one a line
     dds_peer read-kinds DOMAIN N    prints N dds_test.Kinds samples of rt/kinds
     dds_peer write-kinds DOMAIN     writes one known Kinds sample once a reader matches
     dds_peer read-twist DOMAIN N    prints N geometry_msgs/msg/Twist samples of rt/cmd_vel
     dds_peer write-twist DOMAIN     writes one known Twist on rt/cmd_vel once a reader matches
     dds_peer read-imu DOMAIN N      prints N sensor_msgs/msg/Imu samples of rt/imu
     dds_peer write-imu DOMAIN       writes one known Imu on rt/imu once a reader matches
     dds_peer read-scan DOMAIN N     prints N sensor_msgs/msg/LaserScan samples of rt/scan
     dds_peer write-scan DOMAIN      writes one known LaserScan (100 ranges) on rt/scan
     dds_peer read-odom DOMAIN N     prints N nav_msgs/msg/Odometry samples of rt/odom
     dds_peer write-odom DOMAIN      writes one known Odometry on rt/odom
     dds_peer read-pose DOMAIN N     prints N geometry_msgs/msg/PoseStamped samples of rt/pose
     dds_peer write-pose DOMAIN      writes one known PoseStamped on rt/pose
     dds_peer read-image DOMAIN N    prints N horus.msg.ImageDescriptor samples (with the image's
                                     data, as the bridge sends a pool type) of rt/camera
     dds_peer read-tf DOMAIN N       prints the transforms of tf2_msgs/msg/TFMessage samples of
                                     rt/tf (tf2_ros's listener QoS: reliable, volatile, keep-last
                                     100) until it has N, one a line: "SAMPLE parent child sec
                                     nanosec tx,ty,tz qx,qy,qz,qw" (SAMPLE counts samples from 1)
     dds_peer read-tf-static DOMAIN N  the same of rt/tf_static (transient local, keep-last 100)
     dds_peer write-tf DOMAIN [N]    once N readers (default 1) match, writes 3 TFMessages on
                                     rt/tf, each "/map" -> "/odom" and "odom" -> "base_link" at
                                     one stamp
                                     (BASE, BASE+1 s, BASE+2 s: BASE this second), first printing
                                     "base BASE"; the values: write_tf()
     dds_peer write-tf-static DOMAIN writes one TFMessage on rt/tf_static (transient local, keep-
                                     last 1, as tf2_ros's static broadcaster): base_link -> lidar
                                     and base_link -> camera; stays up until killed (the sample
                                     lives as long as its writer)
   Options, anywhere: --topic NAME reads or writes the DDS topic NAME instead; --xcdr2 makes the
   reader or writer use XCDR2 alone (its data representation QoS), and write-kinds then writes
   the name "from C in XCDR2", so that a test can tell its sample from an XCDR1 one.
   It prints "ready" once its reader or writer exists; a timeout (20 s) is exit status 1. */
#include <inttypes.h>
#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "dds/dds.h"
#include "dds_test/Kinds.h"
#include "geometry_msgs/msg/PoseStamped.h"
#include "geometry_msgs/msg/Twist.h"
#include "horus/msg/CmdVel.h"
#include "horus/msg/ImageDescriptor.h"
#include "nav_msgs/msg/Odometry.h"
#include "sensor_msgs/msg/Imu.h"
#include "sensor_msgs/msg/LaserScan.h"
#include "tf2_msgs/msg/TFMessage.h"

static const char *topic_option; /* --topic */
static bool xcdr2_option;        /* --xcdr2 */

static dds_qos_t *reliable(void)
{
  dds_qos_t *qos = dds_create_qos();
  dds_qset_reliability(qos, DDS_RELIABILITY_RELIABLE, DDS_SECS(1));
  dds_qset_history(qos, DDS_HISTORY_KEEP_LAST, 100);
  if (xcdr2_option)
  {
    const dds_data_representation_id_t xcdr2 = DDS_DATA_REPRESENTATION_XCDR2;
    dds_qset_data_representation(qos, 1, &xcdr2);
  }
  return qos;
}

/* tf2_ros's static QoS: transient local, `depth` kept. */
static dds_qos_t *transient_local(int depth)
{
  dds_qos_t *qos = reliable();
  dds_qset_durability(qos, DDS_DURABILITY_TRANSIENT_LOCAL);
  dds_qset_history(qos, DDS_HISTORY_KEEP_LAST, depth);
  return qos;
}

static void print_cmdvel(const void *sample)
{
  const horus_msg_dds__CmdVel_ *s = sample;
  printf("stamp_nanos=%" PRIu64 " linear=%g angular=%g\n", s->stamp_nanos, s->linear, s->angular);
}

static void print_inner(const dds_test_dds__Inner_ *inner)
{
  printf("(%d %g)", inner->flag ? 1 : 0, inner->wide);
}

static void print_kinds(const void *sample)
{
  const dds_test_dds__Kinds_ *s = sample;
  printf("small=%u big=%" PRId64 " mode=%u name=%s tag=%s blob=", s->small, s->big, s->mode,
         s->name, s->tag);
  for (uint32_t i = 0; i < s->blob._length; i++) printf("%02x", s->blob._buffer[i]);
  printf(" raw=");
  for (uint32_t i = 0; i < s->raw._length; i++) printf("%02x", s->raw._buffer[i]);
  printf(" values=");
  for (uint32_t i = 0; i < s->values._length; i++) printf("%s%g", i ? "," : "", s->values._buffer[i]);
  printf(" grid=");
  for (int i = 0; i < 6; i++) printf("%s%d", i ? "," : "", s->grid[i / 3][i % 3]);
  printf(" labels=%s,%s inner=", s->labels[0], s->labels[1]);
  print_inner(&s->inner);
  printf(" inners=");
  for (uint32_t i = 0; i < s->inners._length; i++) print_inner(&s->inners._buffer[i]);
  printf(" maybe=");
  if (s->maybe._length) printf("%g", s->maybe._buffer[0]); else printf("none");
  printf(" nothing=%s points=", s->nothing._length ? "some" : "none");
  for (uint32_t i = 0; i < s->points._length; i++)
    printf("(%g %g %g)", s->points._buffer[i][0], s->points._buffer[i][1], s->points._buffer[i][2]);
  printf(" last=%u\n", s->last);
}

static void print_twist(const void *sample)
{
  const geometry_msgs_msg_dds__Twist_ *s = sample;
  printf("linear=%g,%g,%g angular=%g,%g,%g\n", s->linear.x, s->linear.y, s->linear.z,
         s->angular.x, s->angular.y, s->angular.z);
}

static void print_numbers(const char *name, const double *values, int count)
{
  printf(" %s=", name);
  for (int i = 0; i < count; i++) printf("%s%g", i ? "," : "", values[i]);
}

static void print_imu(const void *sample)
{
  const sensor_msgs_msg_dds__Imu_ *s = sample;
  printf("sec=%d nanosec=%u frame_id=%s", s->header.stamp.sec, s->header.stamp.nanosec,
         s->header.frame_id);
  printf(" orientation=%g,%g,%g,%g", s->orientation.x, s->orientation.y, s->orientation.z,
         s->orientation.w);
  print_numbers("orientation_covariance", s->orientation_covariance, 9);
  printf(" angular_velocity=%g,%g,%g", s->angular_velocity.x, s->angular_velocity.y,
         s->angular_velocity.z);
  print_numbers("angular_velocity_covariance", s->angular_velocity_covariance, 9);
  printf(" linear_acceleration=%g,%g,%g", s->linear_acceleration.x, s->linear_acceleration.y,
         s->linear_acceleration.z);
  print_numbers("linear_acceleration_covariance", s->linear_acceleration_covariance, 9);
  printf("\n");
}

static void print_floats(const char *name, const dds_sequence_float *values)
{
  printf(" %s=", name);
  for (uint32_t i = 0; i < values->_length; i++) printf("%s%g", i ? "," : "", values->_buffer[i]);
}

static void print_scan(const void *sample)
{
  const sensor_msgs_msg_dds__LaserScan_ *s = sample;
  printf("sec=%d nanosec=%u frame_id=%s angles=%g,%g,%g times=%g,%g range=%g,%g",
         s->header.stamp.sec, s->header.stamp.nanosec, s->header.frame_id, s->angle_min,
         s->angle_max, s->angle_increment, s->time_increment, s->scan_time, s->range_min,
         s->range_max);
  print_floats("ranges", &s->ranges);
  print_floats("intensities", &s->intensities);
  printf("\n");
}

static void print_pose(const geometry_msgs_msg_dds__Pose_ *pose)
{
  printf(" position=%g,%g,%g orientation=%g,%g,%g,%g", pose->position.x, pose->position.y,
         pose->position.z, pose->orientation.x, pose->orientation.y, pose->orientation.z,
         pose->orientation.w);
}

static void print_odometry(const void *sample)
{
  const nav_msgs_msg_dds__Odometry_ *s = sample;
  printf("sec=%d nanosec=%u frame_id=%s child_frame_id=%s", s->header.stamp.sec,
         s->header.stamp.nanosec, s->header.frame_id, s->child_frame_id);
  print_pose(&s->pose.pose);
  print_numbers("pose_covariance", s->pose.covariance, 36);
  const geometry_msgs_msg_dds__Twist_ *twist = &s->twist.twist;
  printf(" twist=%g,%g,%g,%g,%g,%g", twist->linear.x, twist->linear.y, twist->linear.z,
         twist->angular.x, twist->angular.y, twist->angular.z);
  print_numbers("twist_covariance", s->twist.covariance, 36);
  printf("\n");
}

static void print_pose_stamped(const void *sample)
{
  const geometry_msgs_msg_dds__PoseStamped_ *s = sample;
  printf("sec=%d nanosec=%u frame_id=%s", s->header.stamp.sec, s->header.stamp.nanosec,
         s->header.frame_id);
  print_pose(&s->pose);
  printf("\n");
}

/* The image's bytes as hex: the test compares them with the pixels it published. */
static void print_image(const void *sample)
{
  const horus_msg_dds__ImageDescriptor_ *s = sample;
  printf("width=%u height=%u encoding=%u channels=%u step=%u data_size=%" PRIu64
         " frame_id=%s timestamp_ns=%" PRIu64 " data=", s->width, s->height, s->encoding,
         s->channels, s->step, s->data_size, s->frame_id, s->timestamp_ns);
  for (uint32_t i = 0; i < s->data._length; i++) printf("%02x", s->data._buffer[i]);
  printf("\n");
}

/* Prints a TFMessage's transforms and returns how many it had. */
static int tf_samples;
static int print_tf(const void *sample)
{
  const tf2_msgs_msg_dds__TFMessage_ *s = sample;
  tf_samples++;
  for (uint32_t i = 0; i < s->transforms._length; i++)
  {
    const geometry_msgs_msg_dds__TransformStamped_ *t = &s->transforms._buffer[i];
    const geometry_msgs_msg_dds__Vector3_ *p = &t->transform.translation;
    const geometry_msgs_msg_dds__Quaternion_ *q = &t->transform.rotation;
    printf("%d %s %s %d %u %.17g,%.17g,%.17g %.17g,%.17g,%.17g,%.17g\n", tf_samples,
           t->header.frame_id, t->child_frame_id, t->header.stamp.sec, t->header.stamp.nanosec,
           p->x, p->y, p->z, q->x, q->y, q->z, q->w);
  }
  return (int) s->transforms._length;
}

/* Reads samples with `qos` (deleted here) until `print` has counted `count` (what each sample
   counts: print's return). */
static int read_samples_counted(dds_entity_t participant, const dds_topic_descriptor_t *type,
                                const char *name, int count, dds_qos_t *qos,
                                int (*print)(const void *))
{
  dds_entity_t topic =
    dds_create_topic(participant, type, topic_option ? topic_option : name, NULL, NULL);
  dds_entity_t reader = dds_create_reader(participant, topic, qos, NULL);
  dds_delete_qos(qos);
  if (reader < 0) { fprintf(stderr, "reader: %s\n", dds_strretcode(reader)); return 1; }
  dds_entity_t waitset = dds_create_waitset(participant);
  dds_waitset_attach(waitset, dds_create_readcondition(reader, DDS_ANY_STATE), 0);
  printf("ready\n");
  fflush(stdout);
  int got = 0;
  while (got < count)
  {
    if (dds_waitset_wait(waitset, NULL, 0, DDS_SECS(20)) <= 0)
    {
      fprintf(stderr, "timed out after %d samples\n", got);
      return 1;
    }
    void *samples[16] = { 0 };
    dds_sample_info_t infos[16];
    int taken = dds_take(reader, samples, infos, 16, 16);
    for (int i = 0; i < taken && got < count; i++)
      if (infos[i].valid_data) got += print(samples[i]);
    fflush(stdout);
    dds_return_loan(reader, samples, taken);
  }
  return 0;
}

static void (*print_plain)(const void *);
static int print_one(const void *sample) { print_plain(sample); return 1; }

static int read_samples(dds_entity_t participant, const dds_topic_descriptor_t *type,
                        const char *name, int count, void (*print)(const void *))
{
  print_plain = print;
  return read_samples_counted(participant, type, name, count, reliable(), print_one);
}

/* Writes `sample` once a reader matches, and waits until it has it. */
static int write_sample(dds_entity_t participant, const dds_topic_descriptor_t *type,
                        const char *name, const void *sample)
{
  dds_entity_t topic =
    dds_create_topic(participant, type, topic_option ? topic_option : name, NULL, NULL);
  dds_qos_t *qos = reliable();
  dds_entity_t writer = dds_create_writer(participant, topic, qos, NULL);
  dds_delete_qos(qos);
  if (writer < 0) { fprintf(stderr, "writer: %s\n", dds_strretcode(writer)); return 1; }
  printf("ready\n");
  fflush(stdout);
  dds_publication_matched_status_t matched = { 0 };
  for (int i = 0; i < 400 && matched.current_count == 0; i++)
  {
    dds_sleepfor(DDS_MSECS(50));
    dds_get_publication_matched_status(writer, &matched);
  }
  if (matched.current_count == 0) { fprintf(stderr, "no reader matched\n"); return 1; }
  dds_return_t code = dds_write(writer, sample);
  if (code < 0) { fprintf(stderr, "write: %s\n", dds_strretcode(code)); return 1; }
  /* Reliable delivery completes before the participant goes away. */
  dds_wait_for_acks(writer, DDS_SECS(10));
  return 0;
}

/* The k-th TFMessage of write-tf (k = 0, 1, 2, at BASE + k s): map -> odom at (k, 0, 0),
   unrotated; odom -> base_link at (0, 2k, 0) turned k * 0.5 rad about z. */
static int write_tf(dds_entity_t participant, uint32_t readers)
{
  dds_entity_t topic = dds_create_topic(participant, &tf2_msgs_msg_dds__TFMessage__desc,
                                        topic_option ? topic_option : "rt/tf", NULL, NULL);
  dds_qos_t *qos = reliable();
  dds_entity_t writer = dds_create_writer(participant, topic, qos, NULL);
  dds_delete_qos(qos);
  if (writer < 0) { fprintf(stderr, "writer: %s\n", dds_strretcode(writer)); return 1; }
  const int32_t base = (int32_t) (dds_time() / DDS_NSECS_IN_SEC);
  printf("ready\nbase %d\n", base);
  fflush(stdout);
  dds_publication_matched_status_t matched = { 0 };
  for (int i = 0; i < 400 && matched.current_count < readers; i++)
  {
    dds_sleepfor(DDS_MSECS(50));
    dds_get_publication_matched_status(writer, &matched);
  }
  if (matched.current_count < readers) { fprintf(stderr, "too few readers matched\n"); return 1; }
  for (int k = 0; k < 3; k++)
  {
    const double half_yaw = 0.25 * k;
    geometry_msgs_msg_dds__TransformStamped_ transforms[2] = {
      { .header = { .stamp = { base + k, 0 }, .frame_id = "/map" }, .child_frame_id = "/odom",
        .transform = { .translation = { k, 0, 0 }, .rotation = { 0, 0, 0, 1 } } },
      { .header = { .stamp = { base + k, 0 }, .frame_id = "odom" }, .child_frame_id = "base_link",
        .transform = { .translation = { 0, 2.0 * k, 0 },
                       .rotation = { 0, 0, sin(half_yaw), cos(half_yaw) } } },
    };
    tf2_msgs_msg_dds__TFMessage_ s = {
      .transforms = { ._length = 2, ._maximum = 2, ._buffer = transforms } };
    dds_return_t code = dds_write(writer, &s);
    if (code < 0) { fprintf(stderr, "write: %s\n", dds_strretcode(code)); return 1; }
  }
  dds_wait_for_acks(writer, DDS_SECS(10));
  return 0;
}

/* Like tf2_ros's static broadcaster: one sample with every static transform, kept for late
   joiners while the writer lives. */
static int write_tf_static(dds_entity_t participant)
{
  dds_entity_t topic = dds_create_topic(participant, &tf2_msgs_msg_dds__TFMessage__desc,
                                        topic_option ? topic_option : "rt/tf_static", NULL, NULL);
  dds_qos_t *qos = transient_local(1);
  dds_entity_t writer = dds_create_writer(participant, topic, qos, NULL);
  dds_delete_qos(qos);
  if (writer < 0) { fprintf(stderr, "writer: %s\n", dds_strretcode(writer)); return 1; }
  geometry_msgs_msg_dds__TransformStamped_ transforms[2] = {
    { .header = { .stamp = { 5, 0 }, .frame_id = "base_link" }, .child_frame_id = "lidar",
      .transform = { .translation = { 0.2, 0, 0.1 }, .rotation = { 0, 0, 0, 1 } } },
    { .header = { .stamp = { 5, 0 }, .frame_id = "/base_link" }, .child_frame_id = "/camera",
      .transform = { .translation = { 0.1, 0, 0.3 }, .rotation = { 0, 0, 0.6, 0.8 } } },
  };
  tf2_msgs_msg_dds__TFMessage_ s = {
    .transforms = { ._length = 2, ._maximum = 2, ._buffer = transforms } };
  dds_return_t code = dds_write(writer, &s);
  if (code < 0) { fprintf(stderr, "write: %s\n", dds_strretcode(code)); return 1; }
  printf("ready\n");
  fflush(stdout);
  for (;;) dds_sleepfor(DDS_SECS(1));
}

static int write_twist(dds_entity_t participant)
{
  geometry_msgs_msg_dds__Twist_ s = { .linear = { 1.5, 0.25, 0 }, .angular = { 0, 0, -0.75 } };
  return write_sample(participant, &geometry_msgs_msg_dds__Twist__desc, "rt/cmd_vel", &s);
}

static int write_imu(dds_entity_t participant)
{
  sensor_msgs_msg_dds__Imu_ s = {
    .header = { .stamp = { 12, 345 }, .frame_id = "imu_link" },
    .orientation = { 0, 0, 0.6, 0.8 },
    .orientation_covariance = { 1, 0, 0, 0, 2, 0, 0, 0, 3 },
    .angular_velocity = { 0.1, -0.2, 0.3 },
    .angular_velocity_covariance = { -1 },
    .linear_acceleration = { 0, 0, 9.81 },
    .linear_acceleration_covariance = { 0.5, 0, 0, 0, 0.5, 0, 0, 0, 0.5 },
  };
  return write_sample(participant, &sensor_msgs_msg_dds__Imu__desc, "rt/imu", &s);
}

static int write_scan(dds_entity_t participant)
{
  float ranges[100];
  for (int i = 0; i < 100; i++) ranges[i] = 0.25f * (float) i;
  float intensities[] = { 7, 8 };
  sensor_msgs_msg_dds__LaserScan_ s = {
    .header = { .stamp = { 3, 500 }, .frame_id = "laser" },
    .angle_min = -1.5f, .angle_max = 1.5f, .angle_increment = 0.03125f,
    .time_increment = 0.001f, .scan_time = 0.125f, .range_min = 0.5f, .range_max = 20.0f,
    .ranges = { ._length = 100, ._maximum = 100, ._buffer = ranges },
    .intensities = { ._length = 2, ._maximum = 2, ._buffer = intensities },
  };
  return write_sample(participant, &sensor_msgs_msg_dds__LaserScan__desc, "rt/scan", &s);
}

static int write_odometry(dds_entity_t participant)
{
  nav_msgs_msg_dds__Odometry_ s = {
    .header = { .stamp = { 4, 6 }, .frame_id = "odom" },
    .child_frame_id = "base_link",
    /* A yaw of 0.5 rad turned 0.1 rad about x too, 0.25 m up: HORUS keeps x, y and the yaw. */
    .pose = { .pose = { .position = { 1, -2, 0.25 },
                        .orientation = { 0.04842543793313918, 0.012365044357817807,
                                         0.2470947687282004, 0.9677015334834238 } },
              .covariance = { 1, 2, 3 } },
    .twist = { .twist = { .linear = { 0.5, 0, 0 }, .angular = { 0, 0, 0.125 } },
               .covariance = { [35] = 9 } },
  };
  return write_sample(participant, &nav_msgs_msg_dds__Odometry__desc, "rt/odom", &s);
}

static int write_pose(dds_entity_t participant)
{
  geometry_msgs_msg_dds__PoseStamped_ s = {
    .header = { .stamp = { 8, 9 }, .frame_id = "map" },
    .pose = { .position = { 1, 2, 3 }, .orientation = { 0, 0, 0.6, 0.8 } },
  };
  return write_sample(participant, &geometry_msgs_msg_dds__PoseStamped__desc, "rt/pose", &s);
}

static int write_kinds(dds_entity_t participant)
{
  uint8_t blob[] = { 1, 2, 3 };
  float values[] = { 0.5f, -2.0f };
  dds_test_dds__Inner_ inners[] = { { true, 1.25 }, { false, -3.5 } };
  dds_test_dds__Kinds__points points[] = { { 1.0f, 2.0f, 3.0f } };
  double maybe = 6.5;
  dds_test_dds__Kinds_ s = {
    .small = 7, .big = -9000000000LL, .mode = 300,
    .name = xcdr2_option ? "from C in XCDR2" : "from C", .tag = "c-tag",
    .blob = { ._length = 3, ._maximum = 3, ._buffer = blob },
    .raw = { ._length = 0 },
    .values = { ._length = 2, ._maximum = 2, ._buffer = values },
    .grid = { { 1, -2, 3 }, { -4, 5, -6 } },
    .labels = { "first", "" },
    .inner = { true, 0.125 },
    .inners = { ._length = 2, ._maximum = 2, ._buffer = inners },
    .maybe = { ._length = 1, ._maximum = 1, ._buffer = &maybe },
    .nothing = { ._length = 0 },
    .points = { ._length = 1, ._maximum = 1, ._buffer = points },
    .last = 255,
  };
  return write_sample(participant, &dds_test_dds__Kinds__desc, "rt/kinds", &s);
}

int main(int argc, char **argv)
{
  int kept = 1;
  for (int i = 1; i < argc; i++)
  {
    if (strcmp(argv[i], "--topic") == 0 && i + 1 < argc)
      topic_option = argv[++i];
    else if (strcmp(argv[i], "--xcdr2") == 0)
      xcdr2_option = true;
    else
      argv[kept++] = argv[i];
  }
  argc = kept;
  if (argc < 3)
  {
    fprintf(stderr, "usage: dds_peer read-cmdvel|read-kinds|write-kinds|read-twist|write-twist|"
                    "read-imu|write-imu|read-scan|write-scan|read-odom|write-odom|read-pose|"
                    "write-pose|read-image|read-tf|read-tf-static|write-tf|write-tf-static "
                    "DOMAIN [N] [--topic NAME] [--xcdr2]\n");
    return 2;
  }
  dds_entity_t participant = dds_create_participant((dds_domainid_t) atoi(argv[2]), NULL, NULL);
  if (participant < 0) { fprintf(stderr, "participant: %s\n", dds_strretcode(participant)); return 1; }
  int count = argc > 3 ? atoi(argv[3]) : 1;
  int status = 2;
  if (strcmp(argv[1], "read-cmdvel") == 0)
    status = read_samples(participant, &horus_msg_dds__CmdVel__desc, "rt/cmd_vel", count, print_cmdvel);
  else if (strcmp(argv[1], "read-kinds") == 0)
    status = read_samples(participant, &dds_test_dds__Kinds__desc, "rt/kinds", count, print_kinds);
  else if (strcmp(argv[1], "write-kinds") == 0)
    status = write_kinds(participant);
  else if (strcmp(argv[1], "read-twist") == 0)
    status = read_samples(participant, &geometry_msgs_msg_dds__Twist__desc, "rt/cmd_vel", count,
                          print_twist);
  else if (strcmp(argv[1], "write-twist") == 0)
    status = write_twist(participant);
  else if (strcmp(argv[1], "read-imu") == 0)
    status = read_samples(participant, &sensor_msgs_msg_dds__Imu__desc, "rt/imu", count, print_imu);
  else if (strcmp(argv[1], "write-imu") == 0)
    status = write_imu(participant);
  else if (strcmp(argv[1], "read-scan") == 0)
    status = read_samples(participant, &sensor_msgs_msg_dds__LaserScan__desc, "rt/scan", count,
                          print_scan);
  else if (strcmp(argv[1], "write-scan") == 0)
    status = write_scan(participant);
  else if (strcmp(argv[1], "read-odom") == 0)
    status = read_samples(participant, &nav_msgs_msg_dds__Odometry__desc, "rt/odom", count,
                          print_odometry);
  else if (strcmp(argv[1], "write-odom") == 0)
    status = write_odometry(participant);
  else if (strcmp(argv[1], "read-pose") == 0)
    status = read_samples(participant, &geometry_msgs_msg_dds__PoseStamped__desc, "rt/pose", count,
                          print_pose_stamped);
  else if (strcmp(argv[1], "write-pose") == 0)
    status = write_pose(participant);
  else if (strcmp(argv[1], "read-tf") == 0)
    status = read_samples_counted(participant, &tf2_msgs_msg_dds__TFMessage__desc, "rt/tf", count,
                                  reliable(), print_tf);
  else if (strcmp(argv[1], "read-tf-static") == 0)
    status = read_samples_counted(participant, &tf2_msgs_msg_dds__TFMessage__desc,
                                  "rt/tf_static", count, transient_local(100), print_tf);
  else if (strcmp(argv[1], "write-tf") == 0)
    status = write_tf(participant, (uint32_t) count);
  else if (strcmp(argv[1], "write-tf-static") == 0)
    status = write_tf_static(participant);
  else if (strcmp(argv[1], "read-image") == 0)
    status = read_samples(participant, &horus_msg_dds__ImageDescriptor__desc, "rt/camera", count,
                          print_image);
  dds_delete(participant);
  return status;
}
