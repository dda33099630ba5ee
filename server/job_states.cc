// The job lifecycle (see job_states.h).
#include "job_states.h"

namespace activefoam::server {

const std::vector<JobTransition>& jobTransitions() {
  using S = v1::JobState;
  static const std::vector<JobTransition> table = {
      {S::JOB_STATE_QUEUED, S::JOB_STATE_RUNNING, "claimed by a worker or handed to Slurm"},
      {S::JOB_STATE_QUEUED, S::JOB_STATE_CANCELLED, "cancelled before it started"},
      {S::JOB_STATE_RUNNING, S::JOB_STATE_SUCCEEDED, "its run ended"},
      {S::JOB_STATE_RUNNING, S::JOB_STATE_FAILED, "its run failed"},
      {S::JOB_STATE_RUNNING, S::JOB_STATE_CANCELLED, "cancelled while running"},
      {S::JOB_STATE_RUNNING, S::JOB_STATE_QUEUED,
       "its worker stopped; it resumes from its checkpoint"},
  };
  return table;
}

bool allowedTransition(v1::JobState from, v1::JobState to) {
  for (const JobTransition& t : jobTransitions())
    if (t.from == from && t.to == to) return true;
  return false;
}

bool isTerminal(v1::JobState s) {
  return s == v1::JOB_STATE_SUCCEEDED || s == v1::JOB_STATE_FAILED || s == v1::JOB_STATE_CANCELLED;
}

}  // namespace activefoam::server
