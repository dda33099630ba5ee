// The job lifecycle: the one table of state changes the store may make. Every change of a job's
// state in the store goes through it (Store's Tx::changeState); anything else is a bug, refused.
//
//   queued ──claim──▶ running ──finish──▶ succeeded | failed | cancelled
//     │  ▲              │
//     │  └──requeue─────┘   (its worker stopped: SIGTERM, a restart, a requeued Slurm task)
//     └──cancel──▶ cancelled
#pragma once

#include <vector>

#include "activefoam/v1/job.pb.h"

namespace activefoam::server {

struct JobTransition {
  v1::JobState from, to;
  const char* why;
};

const std::vector<JobTransition>& jobTransitions();
bool allowedTransition(v1::JobState from, v1::JobState to);
bool isTerminal(v1::JobState s);

}  // namespace activefoam::server
