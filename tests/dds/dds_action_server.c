/* A plain Cyclone DDS program built with idlc from ROS 2's action IDL (as dds_action_client.c
   is; the tests build it), standing in for a ROS 2 action server of tests/schemas/test_actions'
   Navigate: it knows nothing of HORUS but the IDL. Its service samples carry rmw_cyclonedds's
   request header (action_idl/ros2_action_calls.idl).
     dds_action_server DOMAIN
   One goal at a time: a goal sent while one runs is rejected, and so is one whose abort_with is
   "reject". An accepted goal executes at once: feedback_count feedbacks, one each period_us
   (step i, remaining_m = |(x, y)| * (count - i) / count), then Succeeded with {reached, x, y,
   count}; with abort_with "abort", Aborted with {false, 0, 0, count} instead. A cancel of it (by
   its id, or all zero) answers 0 listing it, and the goal ends Canceled at its next step with
   {false, 0, 0, feedbacks sent}; of an ended goal 3, of an unknown one 2. get_result answers
   once the goal has ended (an unknown goal: status 0 at once). Each change of a goal's state
   writes the GoalStatusArray of every goal so far. Lines on stdout:
     ready                       its endpoints made
     goal ID accepted|rejected   ID the goal id's first byte (hex)
     cancel ID CODE              a cancel's goal and return code
   Runs until killed. */
#include <math.h>

#include "action_msgs/msg/GoalStatusArray.h"
#include "horus_test/action/navigate_action.h"
#include "ros2_action_calls.h"
#include "dds_action_common.h"

#define MOST_GOALS 64
enum { UNKNOWN = 0, ACCEPTED = 1, EXECUTING = 2, SUCCEEDED = 4, CANCELED = 5, ABORTED = 6 };

struct goal
{
  action_msgs_msg_dds__GoalInfo_ info;
  int8_t status;
  horus_test_action_dds__Navigate_Goal_ goal;
  uint32_t sent;
  bool cancel;
  dds_time_t next_step;
  horus_test_action_dds__Navigate_Result_ result;
};
static struct goal goals[MOST_GOALS];
static int goal_count;

/* get_result calls held until their goal ends. */
struct held
{
  uint64_t client_id;
  int64_t sequence_number;
  unique_identifier_msgs_msg_dds__UUID_ id;
};
static struct held held[MOST_GOALS];
static int held_count;

static dds_entity_t status_writer, feedback_writer, get_result_reply;

static struct goal *find(const unique_identifier_msgs_msg_dds__UUID_ *id)
{
  for (int i = 0; i < goal_count; i++)
    if (memcmp(goals[i].info.goal_id.uuid, id->uuid, 16) == 0) return &goals[i];
  return NULL;
}

static struct goal *running(void)
{
  for (int i = 0; i < goal_count; i++)
    if (goals[i].status == EXECUTING) return &goals[i];
  return NULL;
}

static void write_status(void)
{
  action_msgs_msg_dds__GoalStatus_ list[MOST_GOALS];
  for (int i = 0; i < goal_count; i++)
  {
    list[i].goal_info = goals[i].info;
    list[i].status = goals[i].status;
  }
  action_msgs_msg_dds__GoalStatusArray_ array = { 0 };
  array.status_list._length = array.status_list._maximum = (uint32_t)goal_count;
  array.status_list._buffer = list;
  dds_write(status_writer, &array);
}

static void answer_result(const struct held *call, int8_t status,
                          const horus_test_action_dds__Navigate_Result_ *result)
{
  ros2_call_GetResultReply reply = { .client_id = call->client_id,
                                     .sequence_number = call->sequence_number };
  reply.response.status = status;
  if (result != NULL) reply.response.result = *result;
  dds_write(get_result_reply, &reply);
}

static void end(struct goal *goal, int8_t status)
{
  goal->status = status;
  write_status();
  for (int i = 0; i < held_count;)
  {
    if (memcmp(held[i].id.uuid, goal->info.goal_id.uuid, 16) != 0) { i++; continue; }
    answer_result(&held[i], status, &goal->result);
    held[i] = held[--held_count];
  }
}

static void step(struct goal *goal)
{
  if (dds_time() < goal->next_step) return;
  const uint32_t count = goal->goal.feedback_count;
  if (goal->cancel || goal->sent == count)
  {
    const bool aborted = strcmp(goal->goal.abort_with, "abort") == 0;
    goal->result.reached = !goal->cancel && !aborted;
    goal->result.final_x = goal->result.reached ? goal->goal.x : 0.0;
    goal->result.final_y = goal->result.reached ? goal->goal.y : 0.0;
    goal->result.feedback_sent = goal->sent;
    end(goal, goal->cancel ? CANCELED : aborted ? ABORTED : SUCCEEDED);
    return;
  }
  goal->sent++;
  horus_test_action_dds__Navigate_FeedbackMessage_ feedback = { .goal_id = goal->info.goal_id };
  feedback.feedback.step = goal->sent;
  feedback.feedback.remaining_m = hypot(goal->goal.x, goal->goal.y) * (count - goal->sent) / count;
  dds_write(feedback_writer, &feedback);
  goal->next_step = dds_time() + DDS_USECS(goal->goal.period_us);
}

int main(int argc, char **argv)
{
  if (argc < 2)
  {
    fprintf(stderr, "usage: dds_action_server DOMAIN\n");
    return 2;
  }
  participant = dds_create_participant((dds_domainid_t)atoi(argv[1]), NULL, NULL);
  if (participant < 0) return 1;
  const char *module = "horus_test::action::dds_::";
  char name[128];
#define NAMED(suffix) (snprintf(name, sizeof name, "%sNavigate_%s", module, suffix), name)
  dds_entity_t send_goal = reader_of(topic_named(&ros2_call_SendGoalRequest_desc,
      NAMED("SendGoal_Request_"), "rq/Navigate/_action/send_goalRequest"), false);
  dds_entity_t send_goal_reply = writer_of(topic_named(&ros2_call_SendGoalReply_desc,
      NAMED("SendGoal_Response_"), "rr/Navigate/_action/send_goalReply"));
  dds_entity_t get_result = reader_of(topic_named(&ros2_call_GetResultRequest_desc,
      NAMED("GetResult_Request_"), "rq/Navigate/_action/get_resultRequest"), false);
  get_result_reply = writer_of(topic_named(&ros2_call_GetResultReply_desc,
      NAMED("GetResult_Response_"), "rr/Navigate/_action/get_resultReply"));
  dds_entity_t cancel = reader_of(topic_named(&ros2_call_CancelGoalRequest_desc,
      "action_msgs::srv::dds_::CancelGoal_Request_", "rq/Navigate/_action/cancel_goalRequest"),
      false);
  dds_entity_t cancel_reply = writer_of(topic_named(&ros2_call_CancelGoalReply_desc,
      "action_msgs::srv::dds_::CancelGoal_Response_", "rr/Navigate/_action/cancel_goalReply"));
  feedback_writer = writer_of(topic_named(&horus_test_action_dds__Navigate_FeedbackMessage__desc,
      NAMED("FeedbackMessage_"), "rt/Navigate/_action/feedback"));
  /* ROS 2's status QoS: reliable, transient local. */
  dds_qos_t *latched = reliable(true);
  status_writer = dds_create_writer(participant, topic_named(&action_msgs_msg_dds__GoalStatusArray__desc,
      "action_msgs::msg::dds_::GoalStatusArray_", "rt/Navigate/_action/status"), latched, NULL);
  dds_delete_qos(latched);
  printf("ready\n");
  fflush(stdout);

  for (;;)
  {
    void *samples[16] = { 0 };
    dds_sample_info_t infos[16];
    int taken = dds_take(send_goal, samples, infos, 16, 16);
    for (int i = 0; i < taken; i++)
    {
      const ros2_call_SendGoalRequest *request = samples[i];
      if (!infos[i].valid_data) continue;
      const bool accept = running() == NULL && goal_count < MOST_GOALS &&
                          strcmp(request->request.goal.abort_with, "reject") != 0;
      const dds_time_t now = dds_time();
      ros2_call_SendGoalReply reply = { .client_id = request->client_id,
                                        .sequence_number = request->sequence_number };
      reply.response.accepted = accept;
      reply.response.stamp.sec = (int32_t)(now / DDS_NSECS_IN_SEC);
      reply.response.stamp.nanosec = (uint32_t)(now % DDS_NSECS_IN_SEC);
      dds_write(send_goal_reply, &reply);
      printf("goal %02x %s\n", request->request.goal_id.uuid[0], accept ? "accepted" : "rejected");
      if (!accept) continue;
      struct goal *goal = &goals[goal_count++];
      memset(goal, 0, sizeof *goal);
      goal->info.goal_id = request->request.goal_id;
      goal->info.stamp = reply.response.stamp;
      goal->goal = request->request.goal;
      goal->status = ACCEPTED;
      write_status();
      goal->status = EXECUTING;
      write_status();
    }
    if (taken > 0) dds_return_loan(send_goal, samples, taken);

    taken = dds_take(cancel, samples, infos, 16, 16);
    for (int i = 0; i < taken; i++)
    {
      const ros2_call_CancelGoalRequest *request = samples[i];
      if (!infos[i].valid_data) continue;
      const unique_identifier_msgs_msg_dds__UUID_ *id = &request->request.goal_info.goal_id;
      static const uint8_t all[16];
      struct goal *goal = memcmp(id->uuid, all, 16) == 0 ? running() : find(id);
      ros2_call_CancelGoalReply reply = { .client_id = request->client_id,
                                          .sequence_number = request->sequence_number };
      action_msgs_msg_dds__GoalInfo_ listed[1];
      if (goal != NULL && goal->status == EXECUTING)
      {
        goal->cancel = true;
        listed[0] = goal->info;
        reply.response.goals_canceling._buffer = listed;
        reply.response.goals_canceling._length = reply.response.goals_canceling._maximum = 1;
      }
      reply.response.return_code = goal == NULL ? 2 : goal->status == EXECUTING ? 0 : 3;
      dds_write(cancel_reply, &reply);
      printf("cancel %02x %d\n", id->uuid[0], reply.response.return_code);
    }
    if (taken > 0) dds_return_loan(cancel, samples, taken);

    taken = dds_take(get_result, samples, infos, 16, 16);
    for (int i = 0; i < taken; i++)
    {
      const ros2_call_GetResultRequest *request = samples[i];
      if (!infos[i].valid_data) continue;
      const struct held call = { request->client_id, request->sequence_number,
                                 request->request.goal_id };
      const struct goal *goal = find(&call.id);
      if (goal == NULL)
        answer_result(&call, UNKNOWN, NULL);
      else if (goal->status >= SUCCEEDED)
        answer_result(&call, goal->status, &goal->result);
      else if (held_count < MOST_GOALS)
        held[held_count++] = call;
    }
    if (taken > 0) dds_return_loan(get_result, samples, taken);

    struct goal *goal = running();
    if (goal != NULL) step(goal);
    fflush(stdout);
    dds_sleepfor(DDS_MSECS(1));
  }
}
