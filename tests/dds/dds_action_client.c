/* A plain Cyclone DDS program built with idlc from ROS 2's action IDL (horus-gen's
   navigate_action.idl of tests/schemas/test_actions, action_msgs and unique_identifier_msgs from
   bridges/dds/ros2_idl/; the tests build it), standing in for a ROS 2 action client of
   Navigate: it knows nothing of HORUS but the IDL. Its service samples carry rmw_cyclonedds's
   request header (action_idl/ros2_action_calls.idl).
     dds_action_client DOMAIN X Y COUNT PERIOD_US [CANCEL_AFTER]
   Sends goal 01 02 .. 10 (x, y, feedback_count, period_us), asks its result at once (as rclcpp
   does), and after its first feedback sends goal b0 b1 .. bf, which a server of the Reject
   policy refuses; with CANCEL_AFTER, cancels goal 01 after that many feedbacks. Lines on stdout:
     accepted 1 STAMP_SEC>0          send_goal's answer of goal 01
     feedback STEP REMAINING         each feedback of goal 01
     second accepted 0|1             send_goal's answer of goal b0
     status ID:STATE ...             each GoalStatusArray (ID the goal id's first byte, hex)
     cancel CODE N FIRST             cancel_goal's answer: return code, goals listed, the first's
                                     first byte (hex, or -)
     result STATUS REACHED X Y SENT  get_result's answer, then the program ends (exit 0)
   Exit 1 when something does not come within 20 s. */
#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "dds/dds.h"
#include "action_msgs/msg/GoalStatusArray.h"
#include "horus_test/action/navigate_action.h"
#include "ros2_action_calls.h"
#include "dds_action_common.h"

static void goal_id(unique_identifier_msgs_msg_dds__UUID_ *id, uint8_t first)
{
  for (int i = 0; i < 16; i++) id->uuid[i] = (uint8_t)(first + i);
}

int main(int argc, char **argv)
{
  if (argc < 6)
  {
    fprintf(stderr, "usage: dds_action_client DOMAIN X Y COUNT PERIOD_US [CANCEL_AFTER]\n");
    return 2;
  }
  const uint32_t count = (uint32_t)atoi(argv[4]);
  const int cancel_after = argc > 6 ? atoi(argv[6]) : -1;
  participant = dds_create_participant((dds_domainid_t)atoi(argv[1]), NULL, NULL);
  if (participant < 0) return 1;
  const char *module = "horus_test::action::dds_::";
  char name[128];
#define NAMED(suffix) (snprintf(name, sizeof name, "%sNavigate_%s", module, suffix), name)
  dds_entity_t send_goal = writer_of(topic_named(&ros2_call_SendGoalRequest_desc,
      NAMED("SendGoal_Request_"), "rq/Navigate/_action/send_goalRequest"));
  dds_entity_t send_goal_reply = reader_of(topic_named(&ros2_call_SendGoalReply_desc,
      NAMED("SendGoal_Response_"), "rr/Navigate/_action/send_goalReply"), false);
  dds_entity_t get_result = writer_of(topic_named(&ros2_call_GetResultRequest_desc,
      NAMED("GetResult_Request_"), "rq/Navigate/_action/get_resultRequest"));
  dds_entity_t get_result_reply = reader_of(topic_named(&ros2_call_GetResultReply_desc,
      NAMED("GetResult_Response_"), "rr/Navigate/_action/get_resultReply"), false);
  dds_entity_t cancel = writer_of(topic_named(&ros2_call_CancelGoalRequest_desc,
      "action_msgs::srv::dds_::CancelGoal_Request_", "rq/Navigate/_action/cancel_goalRequest"));
  dds_entity_t cancel_reply = reader_of(topic_named(&ros2_call_CancelGoalReply_desc,
      "action_msgs::srv::dds_::CancelGoal_Response_", "rr/Navigate/_action/cancel_goalReply"),
      false);
  dds_entity_t feedback = reader_of(topic_named(&horus_test_action_dds__Navigate_FeedbackMessage__desc,
      NAMED("FeedbackMessage_"), "rt/Navigate/_action/feedback"), false);
  dds_entity_t status = reader_of(topic_named(&action_msgs_msg_dds__GoalStatusArray__desc,
      "action_msgs::msg::dds_::GoalStatusArray_", "rt/Navigate/_action/status"), true);

  /* As rclcpp's action client waits for its server: every endpoint matched. */
  const dds_time_t give_up = dds_time() + DDS_SECS(20);
  while (!(matched(send_goal, true) && matched(get_result, true) && matched(cancel, true) &&
           matched(send_goal_reply, false) && matched(get_result_reply, false) &&
           matched(cancel_reply, false) && matched(feedback, false) && matched(status, false)))
  {
    if (dds_time() > give_up) { fprintf(stderr, "no action server on DDS\n"); return 1; }
    dds_sleepfor(DDS_MSECS(10));
  }

  ros2_call_SendGoalRequest goal = { .client_id = 42, .sequence_number = 1 };
  goal_id(&goal.request.goal_id, 0x01);
  goal.request.goal.x = atof(argv[2]);
  goal.request.goal.y = atof(argv[3]);
  goal.request.goal.feedback_count = count;
  goal.request.goal.period_us = (uint32_t)atoi(argv[5]);
  dds_write(send_goal, &goal);
  ros2_call_GetResultRequest result = { .client_id = 42, .sequence_number = 2 };
  goal_id(&result.request.goal_id, 0x01);
  bool result_asked = false, second_sent = false, canceled = false;
  int feedbacks = 0;

  while (dds_time() < give_up)
  {
    void *samples[16] = { 0 };
    dds_sample_info_t infos[16];
    int taken = dds_take(send_goal_reply, samples, infos, 16, 16);
    for (int i = 0; i < taken; i++)
    {
      const ros2_call_SendGoalReply *reply = samples[i];
      if (!infos[i].valid_data || reply->client_id != 42) continue;
      if (reply->sequence_number == 1)
      {
        printf("accepted %d %d\n", reply->response.accepted, reply->response.stamp.sec > 0);
        dds_write(get_result, &result);
        result_asked = true;
      }
      else if (reply->sequence_number == 3)
        printf("second accepted %d\n", reply->response.accepted);
    }
    if (taken > 0) dds_return_loan(send_goal_reply, samples, taken);

    taken = dds_take(feedback, samples, infos, 16, 16);
    for (int i = 0; i < taken; i++)
    {
      const horus_test_action_dds__Navigate_FeedbackMessage_ *message = samples[i];
      if (!infos[i].valid_data || message->goal_id.uuid[0] != 0x01) continue;
      printf("feedback %u %.6f\n", message->feedback.step, message->feedback.remaining_m);
      feedbacks++;
    }
    if (taken > 0) dds_return_loan(feedback, samples, taken);
    if (feedbacks > 0 && !second_sent)
    {
      ros2_call_SendGoalRequest second = { .client_id = 42, .sequence_number = 3 };
      goal_id(&second.request.goal_id, 0xb0);
      second.request.goal.feedback_count = 1;
      dds_write(send_goal, &second);
      second_sent = true;
    }
    if (cancel_after >= 0 && feedbacks >= cancel_after && !canceled)
    {
      ros2_call_CancelGoalRequest request = { .client_id = 42, .sequence_number = 4 };
      goal_id(&request.request.goal_info.goal_id, 0x01);
      dds_write(cancel, &request);
      canceled = true;
    }

    taken = dds_take(cancel_reply, samples, infos, 16, 16);
    for (int i = 0; i < taken; i++)
    {
      const ros2_call_CancelGoalReply *reply = samples[i];
      if (!infos[i].valid_data || reply->client_id != 42 || reply->sequence_number != 4) continue;
      const uint32_t listed = reply->response.goals_canceling._length;
      if (listed > 0)
        printf("cancel %d %u %02x\n", reply->response.return_code, listed,
               reply->response.goals_canceling._buffer[0].goal_id.uuid[0]);
      else
        printf("cancel %d 0 -\n", reply->response.return_code);
    }
    if (taken > 0) dds_return_loan(cancel_reply, samples, taken);

    taken = dds_take(status, samples, infos, 16, 16);
    for (int i = 0; i < taken; i++)
    {
      const action_msgs_msg_dds__GoalStatusArray_ *array = samples[i];
      if (!infos[i].valid_data) continue;
      printf("status");
      for (uint32_t k = 0; k < array->status_list._length; k++)
        printf(" %02x:%d", array->status_list._buffer[k].goal_info.goal_id.uuid[0],
               array->status_list._buffer[k].status);
      printf("\n");
    }
    if (taken > 0) dds_return_loan(status, samples, taken);

    taken = dds_take(get_result_reply, samples, infos, 16, 16);
    for (int i = 0; i < taken; i++)
    {
      const ros2_call_GetResultReply *reply = samples[i];
      if (!infos[i].valid_data || reply->client_id != 42 || reply->sequence_number != 2) continue;
      printf("result %d %d %.6f %.6f %u\n", reply->response.status,
             reply->response.result.reached, reply->response.result.final_x,
             reply->response.result.final_y, reply->response.result.feedback_sent);
      fflush(stdout);
      dds_return_loan(get_result_reply, samples, taken);
      dds_delete(participant);
      return 0;
    }
    if (taken > 0) dds_return_loan(get_result_reply, samples, taken);
    fflush(stdout);
    dds_sleepfor(DDS_MSECS(2));
  }
  fprintf(stderr, "no result within 20 s (asked: %d)\n", result_asked);
  return 1;
}
