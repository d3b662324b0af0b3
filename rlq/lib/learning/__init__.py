"""What the learning algorithms are made of: networks and their initialisers, action distributions, optimisers and
schedules, advantages, minibatches, running normalisation and the replay buffer."""
